// pi.h - PI speed controller in fixed point with anti-windup, output and slew limits.
//
// Units: error e in mrad/s, clamped to +-PI_ERR_CLAMP and handled as sign and 16-bit magnitude;
// output u in Q15 drive level (32767 = full supply voltage amplitude).
// kp_q8: Q15 counts per mrad/s, times 256.  ki_q8: Q15 counts per mrad/s per tick, times 256.
// u = (kp*e)/256 + I/256, I += ki*e each tick. The clamp of e only acts where a sane kp saturates
// the output anyway (65.5 rad/s error).
// Anti-windup: I is clamped to +-out_max*256; while the output or slew limit holds the output in
// the direction the error pushes it, I grows at most to the value that just reaches the limit
// (back-calculation), so it releases at once when the error reverses.
// Widths: kp * |e| < 2^31 and ki * |e| < 2^31 are 16 x 16 -> 32 multiplies; |I| <= 2^23; the
// proportional term is used clamped to +-65535 (beyond that the output saturates whatever I is),
// so u = P + I/256 stays within +-2^17.
#ifndef PI_H
#define PI_H

#include <stdint.h>

#include "port_progmem.h"

#define PI_ERR_CLAMP 65535L

struct pi_gains {
    int16_t kp_q8;    // 0..32767 (negative gains are not supported)
    int16_t ki_q8;    // 0..32767
    int16_t out_max;  // 0..32767
    int16_t slew;     // max output change per tick, 1..32767
};

struct pi_state {
    port_i24 integ;     // integral term times 256, |integ| <= out_max * 256 <= 2^23
    int16_t out;        // last output, Q15
    uint8_t saturated;  // 1 if the last output was limited
};

void pi_reset(pi_state* s);

// Gains as pi_step_mag expects them: out_max >= 0, slew >= 1 (once per parameter change).
pi_gains pi_gains_sanitize(pi_gains g);

// Setpoint and measurement in mrad/s (|each| < 2^30); gains as given (sanitised here).
int16_t pi_step(pi_state* s, const pi_gains* g, int32_t setpoint, int32_t measured);

// The step itself, on the error as sign (neg: setpoint below measurement) and magnitude
// (mrad/s, <= PI_ERR_CLAMP; 0 with neg false for no error), with sanitised gains. A negative error
// is mirrored onto a positive one (I, lo and hi negated and swapped; I / 256 then rounds up
// instead of down), so one path computes both. pi_step_mag_c is the reference in C (32-bit
// intermediates); on AVR pi_step_mag calls pi_step_mag_avr (pi_avr.cpp, hand-written assembly,
// compared with pi_step_mag_c on the chip by `make -C firmware port-check`).
PORT_INLINE int16_t pi_step_mag_c(pi_state* s, const pi_gains* g, bool neg, uint16_t mag) {
    // Proportional term, floor(kp * e / 256) for either sign, its magnitude clamped to 65535
    // (beyond it the output saturates whatever I is).
    uint32_t p = port_mul_u16(static_cast<uint16_t>(g->kp_q8), mag);
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
    uint32_t di = port_mul_u16(static_cast<uint16_t>(g->ki_q8), mag);
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

#if defined(__AVR__)
// Not an avr-gcc ABI function: it takes the arguments in the ABI's registers (r24:r25 s,
// r22:r23 g, r20 neg, r18:r19 mag) and returns y in r24:r25, but clobbers the call-saved r12..r17
// as well (saving them cost 24 cycles per call; the control step's caller has them saved in its
// own prologue anyway). Only called through pi_step_mag below, which tells the compiler.
extern "C" void pi_step_mag_avr();
#endif

PORT_INLINE int16_t pi_step_mag(pi_state* s, const pi_gains* g, bool neg, uint16_t mag) {
#if defined(__AVR__)
    register uint16_t r_s __asm__("r24") = static_cast<uint16_t>(reinterpret_cast<uintptr_t>(s));
    register uint16_t r_g __asm__("r22") = static_cast<uint16_t>(reinterpret_cast<uintptr_t>(g));
    register uint8_t r_neg __asm__("r20") = neg;
    register uint16_t r_mag __asm__("r18") = mag;
    __asm__ __volatile__("call pi_step_mag_avr"
                         : "+r"(r_s), "+r"(r_g), "+r"(r_neg), "+r"(r_mag)
                         :
                         : "r0", "r12", "r13", "r14", "r15", "r16", "r17", "r21", "r26", "r27",
                           "r30", "r31", "memory");
    return static_cast<int16_t>(r_s);
#else
    return pi_step_mag_c(s, g, neg, mag);
#endif
}

#endif  // PI_H
