#include "pi.h"

#include "port_progmem.h"

static int32_t clamp32(int32_t x, int32_t lo, int32_t hi) {
    if (x < lo) return lo;
    if (x > hi) return hi;
    return x;
}

void pi_reset(pi_state* s) {
    s->integ = 0;
    s->out = 0;
    s->saturated = 0;
}

int16_t pi_step(pi_state* s, const pi_gains* g, int32_t setpoint, int32_t measured) {
    // Inputs are bounded speeds (|x| < 2^24), so the difference cannot overflow. The error is
    // clamped to +-PI_ERR_CLAMP and handled as sign and 16-bit magnitude, so both products are
    // 16 x 16 -> 32 multiplies (gains >= 0): |kp * e| <= 32767 * 65535 < 2^31.
    int32_t e32 = setpoint - measured;
    const bool neg = e32 < 0;
    uint16_t mag;
    if (e32 > PI_ERR_CLAMP || e32 < -PI_ERR_CLAMP) {
        mag = static_cast<uint16_t>(PI_ERR_CLAMP);
    } else {
        mag = static_cast<uint16_t>(neg ? -e32 : e32);
    }
    uint32_t p = port_mul_u16(static_cast<uint16_t>(g->kp_q8), mag);
    // p8 = floor(kp * e / 256) for either sign (an arithmetic shift of the signed product).
    int32_t p8 = neg ? -static_cast<int32_t>((p + 255u) >> 8) : static_cast<int32_t>(p >> 8);

    const int16_t out_max = g->out_max < 0 ? 0 : g->out_max;
    const int16_t slew = g->slew < 1 ? 1 : g->slew;
    const int16_t out = s->out;  // |out| <= 32767
    // lo = max(out - slew, -out_max), hi = min(out + slew, out_max) without leaving int16.
    int16_t lo =
        out >= slew - out_max ? static_cast<int16_t>(out - slew) : static_cast<int16_t>(-out_max);
    int16_t hi = out <= out_max - slew ? static_cast<int16_t>(out + slew) : out_max;
    if (lo > hi) lo = hi;  // out_max shrank below the last output: move towards it

    const int32_t ilim = static_cast<int32_t>(out_max) << 8;
    // di = ki * e clamped to +-2 * ilim (|both| <= 2^24: the sum below cannot overflow).
    uint32_t di = port_mul_u16(static_cast<uint16_t>(g->ki_q8), mag);
    const uint32_t di_max = static_cast<uint32_t>(ilim) << 1;
    if (di > di_max) di = di_max;
    int32_t integ = neg ? s->integ - static_cast<int32_t>(di) : s->integ + static_cast<int32_t>(di);
    integ = clamp32(integ, -ilim, ilim);
    // Back-calculation: while a limit holds the output in the direction the error pushes, the
    // integrator may only grow up to the value that just reaches the limit (never beyond it,
    // and never shrinking because of the clamp itself).
    int32_t u = p8 + (integ >> 8);
    if (!neg && mag != 0 && u > hi) {
        int32_t cap = clamp32(hi - p8, -out_max, out_max) * 256;
        integ = cap > s->integ ? cap : s->integ;
        if (integ > ilim) integ = ilim;
        u = p8 + (integ >> 8);
    } else if (neg && u < lo) {
        int32_t cap = clamp32(lo - p8, -out_max, out_max) * 256;
        integ = cap < s->integ ? cap : s->integ;
        if (integ < -ilim) integ = -ilim;
        u = p8 + (integ >> 8);
    }
    s->integ = integ;
    int16_t y;
    if (u > hi) {
        y = hi;
    } else if (u < lo) {
        y = lo;
    } else {
        y = static_cast<int16_t>(u);
    }
    s->saturated = (y != u) ? 1 : 0;
    s->out = y;
    return y;
}
