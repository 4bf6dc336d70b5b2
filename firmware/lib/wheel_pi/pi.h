// pi.h - PI speed controller in fixed point with anti-windup, output and slew limits.
//
// Units: error e in the controller's error unit (the control step passes q8 speed units, speed.h),
// clamped to +-PI_ERR_CLAMP; output u in Q15 drive level (32767 = full supply voltage amplitude).
// kp_q8: Q15 counts per error unit, times 256.  ki_q8: Q15 counts per error unit per tick, times
// 256. u = (kp*e)/256 + I/256, I += ki*e each tick. The clamp of e only acts where a sane kp
// saturates the output anyway.
// Anti-windup: I is clamped to +-out_max*256; while the output or slew limit holds the output in
// the direction the error pushes it, I grows at most to the value that just reaches the limit
// (back-calculation), so it releases at once when the error reverses.
// Widths: gains are unsigned 16-bit, so kp * |e| and ki * |e| are 16 x 16 -> 32 unsigned
// multiplies (< 2^32); |I| <= 2^23; the proportional term is used clamped to +-65535 (beyond that
// the output saturates whatever I is), so u = P + I/256 stays within +-2^17.
#ifndef PI_H
#define PI_H

#include <stdint.h>

#include "port_progmem.h"

#define PI_ERR_CLAMP 65535L

struct pi_gains {
    uint16_t kp_q8;   // 0..65535 (negative gains are not supported)
    uint16_t ki_q8;   // 0..65535
    int16_t out_max;  // 0..32767
    int16_t slew;     // max output change per tick, 1..32767
};

struct pi_state {
    port_i24 integ;     // integral term times 256, |integ| <= out_max * 256 <= 2^23
    int16_t out;        // last output, Q15
    uint8_t saturated;  // 1 if the last output was limited
};

void pi_reset(pi_state* s);

// Gains as pi_step_err expects them: out_max >= 0, slew >= 1 (once per parameter change).
pi_gains pi_gains_sanitize(pi_gains g);

// Setpoint and measurement in the error unit (|each| < 2^30); gains as given (sanitised here).
int16_t pi_step(pi_state* s, const pi_gains* g, int32_t setpoint, int32_t measured);

// The step on the error as sign (neg: setpoint below measurement) and magnitude (<= PI_ERR_CLAMP;
// 0 with neg false for no error), with sanitised gains: the reference in C (32-bit
// intermediates) that pi_step_err_c and the native tests run. A negative error is mirrored onto a
// positive one (I, lo and hi negated and swapped; I / 256 then rounds up instead of down), so one
// path computes both; the AVR assembly (pi_step_err_avr) computes the same in the signed domain.
PORT_INLINE int16_t pi_step_mag_c(pi_state* s, const pi_gains* g, bool neg, uint16_t mag) {
    // Proportional term, floor(kp * e / 256) for either sign, its magnitude clamped to 65535
    // (beyond it the output saturates whatever I is).
    uint32_t p = port_mul_u16(g->kp_q8, mag);
    if (neg) p += 255u;  // ceil of the magnitude: floor of the negative value
    const int32_t pm = (p >> 24) ? 0xFFFF : static_cast<int32_t>(p >> 8);

    const int16_t out_max = g->out_max;
    const int16_t slew = g->slew;
    const int16_t out = s->out;  // |out| <= 32767
    // lo = max(out - slew, -out_max), hi = min(out + slew, out_max) without leaving int16.
    int16_t lo =
        out >= slew - out_max ? static_cast<int16_t>(out - slew) : static_cast<int16_t>(-out_max);
    int16_t hi = out <= out_max - slew ? static_cast<int16_t>(out + slew) : out_max;
    if (lo > hi) lo = hi;  // out_max shrank below the last output: move towards it

    int32_t prev = s->integ;
    int32_t round = 0;  // added before I / 256: 255 in the mirrored case (ceil)
    if (neg) {
        prev = -prev;
        const int16_t t = lo;
        lo = static_cast<int16_t>(-hi);
        hi = static_cast<int16_t>(-t);
        round = 255;
    }
    // Integrator: I + ki * e, the increment clamped to 2 * ilim, the sum to +-ilim (2^23).
    const int32_t ilim = static_cast<int32_t>(out_max) << 8;
    uint32_t di = port_mul_u16(g->ki_q8, mag);
    if (di > static_cast<uint32_t>(ilim) << 1) di = static_cast<uint32_t>(ilim) << 1;
    int32_t integ = prev + static_cast<int32_t>(di);
    if (integ > ilim) {
        integ = ilim;
    } else if (integ < -ilim) {
        integ = -ilim;
    }
    // u = P + I / 256 within +-2^17.
    int32_t u = pm + ((integ + round) >> 8);
    // Back-calculation: while a limit holds the output in the direction the error pushes, the
    // integrator may only grow up to the value that just reaches the limit (never beyond it,
    // and never shrinking because of the clamp itself).
    if (mag != 0 && u > hi) {
        int32_t c = hi - pm;
        if (c < -out_max) c = -out_max;
        // c > out_max (mirrored hi above out_max after out_max shrank) needs no clamp: I is
        // clamped to ilim below anyway.
        const int32_t cap = c * 256;
        integ = cap > prev ? cap : prev;
        if (integ > ilim) integ = ilim;
        u = pm + ((integ + round) >> 8);
    }
    int16_t y;
    uint8_t sat = 1;
    if (u > hi) {
        y = hi;
    } else if (u < lo) {
        y = lo;
    } else {
        y = static_cast<int16_t>(u);
        sat = 0;
    }
    if (neg) {
        integ = -integ;
        y = static_cast<int16_t>(-y);
    }
    s->integ = static_cast<port_i24>(integ);
    s->saturated = sat;
    s->out = y;
    return y;
}

// The step on the signed error e (setpoint - measured, |e| < 2^31), clamped to +-PI_ERR_CLAMP:
// exactly pi_step_mag_c(s, g, e < 0, min(|e|, PI_ERR_CLAMP)). What the control step calls, as
// pi_step_err below (on AVR the assembly pi_step_err_avr; `make -C firmware port-check` compares
// the two on the chip).
PORT_INLINE int16_t pi_step_err_c(pi_state* s, const pi_gains* g, int32_t e) {
    uint16_t mag;
    if (e > PI_ERR_CLAMP || e < -PI_ERR_CLAMP) {
        mag = static_cast<uint16_t>(PI_ERR_CLAMP);
    } else {
        mag = static_cast<uint16_t>(e < 0 ? -e : e);
    }
    return pi_step_mag_c(s, g, e < 0, mag);
}

#if defined(__AVR__)
// pi_step_err on the chip: the assembly of pi_avr.cpp, which saves about 970 cycles of the
// 1 ms control step (docs/hardware.md, "Control-step cycles"). Its call convention is in pi_avr.h.
#include "pi_avr.h"
#else
PORT_INLINE int16_t pi_step_err(pi_state* s, const pi_gains* g, int32_t e) {
    return pi_step_err_c(s, g, e);
}
#endif

#endif  // PI_H
