#include "pi.h"

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
    // Inputs are bounded speeds (|x| < 2^24), so the difference cannot overflow.
    int32_t e = clamp32(setpoint - measured, -PI_ERR_CLAMP, PI_ERR_CLAMP);
    int32_t p = static_cast<int32_t>(g->kp_q8) * e;  // |p| <= 32767 * 65535 < 2^31
    int32_t di = static_cast<int32_t>(g->ki_q8) * e;

    int32_t out_max = g->out_max < 0 ? 0 : g->out_max;
    int32_t slew = g->slew < 1 ? 1 : g->slew;
    int32_t lo = static_cast<int32_t>(s->out) - slew;
    int32_t hi = static_cast<int32_t>(s->out) + slew;
    if (lo < -out_max) lo = -out_max;
    if (hi > out_max) hi = out_max;
    if (lo > hi) lo = hi;  // out_max shrank below the last output: move towards it

    int32_t ilim = out_max << 8;
    int32_t p8 = p >> 8;
    int32_t integ = s->integ + clamp32(di, -2 * ilim, 2 * ilim);  // no overflow: |both| <= 2^24
    integ = clamp32(integ, -ilim, ilim);
    // Back-calculation: while a limit holds the output in the direction the error pushes, the
    // integrator may only grow up to the value that just reaches the limit (never beyond it,
    // and never shrinking because of the clamp itself).
    if (e > 0 && p8 + (integ >> 8) > hi) {
        int32_t cap = clamp32(hi - p8, -out_max, out_max) * 256;
        integ = cap > s->integ ? cap : s->integ;
        if (integ > ilim) integ = ilim;
    } else if (e < 0 && p8 + (integ >> 8) < lo) {
        int32_t cap = clamp32(lo - p8, -out_max, out_max) * 256;
        integ = cap < s->integ ? cap : s->integ;
        if (integ < -ilim) integ = -ilim;
    }
    int32_t u = p8 + (integ >> 8);
    s->integ = integ;
    int32_t y = clamp32(u, lo, hi);
    s->saturated = (y != u) ? 1 : 0;
    s->out = static_cast<int16_t>(y);
    return s->out;
}
