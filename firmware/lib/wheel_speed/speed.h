// speed.h - fixed-point wheel speed estimator from 14-bit encoder angles sampled at the control
// tick.
//
// Speed unit inside the firmware: encoder counts per 1 ms tick in Q8 ("q8", int32 holding at most
// 22 bits): 1 unit = 2*pi/16384/256 rad per ms = 1.4980 mrad/s; 715 rpm = 49979 q8. mrad/s only at
// the protocol boundary (spd_q8_to_mrad_s, spd_mrad_s_to_q8). Angle differences are wrapped at 14
// bits, so a delta is unambiguous up to +-8191 counts per tick (30000 rpm): |speed| <= 2^21 q8.
// Filter: first-order low pass y += (x - y) / 2^shift with x = delta * 256 (q8), kept as
// acc = y * 2^16 exactly (a constant input gives exactly that output). Per update
//   acc += k * (x - (acc >> 8)),  k = 2^(8 - shift),
// which is acc' = acc + x - (acc >> shift) on acc scaled by 2^(8 - shift): the shift only changes
// the multiplier (one 24 x 8 multiply, no variable shift), and a change of shift leaves the
// estimate where it was. |x - y| <= 2^22, |k * (x - y)| <= 2^29, |acc| <= 2^29.
#ifndef SPEED_H
#define SPEED_H

#include <stdint.h>

#include "port_progmem.h"

#define SPD_TICK_HZ 1000
#define SPD_MAX_SHIFT 8
#define SPD_Q8_PER_COUNT 256L

struct spd_state {
    int32_t acc;          // filtered speed, q8 * 256 (counts per tick * 2^16)
    uint16_t last_angle;  // last good 14-bit angle
    uint8_t primed;       // 0 until the first good angle
    uint8_t missed;       // ticks since the last good angle, minus one
};

void spd_init(spd_state* s);

// Filter multiplier k = 2^(8 - shift) of spd_update; shift is clamped to SPD_MAX_SHIFT. Computed
// once per parameter change. k = 0 stands for 256 (shift 0: no filtering).
uint8_t spd_gain(uint8_t shift);

// Signed difference b - a of two 14-bit angles, wrapped into [-8192, 8191] counts.
PORT_INLINE int16_t spd_wrap_delta(uint16_t a, uint16_t b) {
    // Shift the 14-bit difference into the top of a 16-bit word, then back with sign extension.
    uint16_t d = static_cast<uint16_t>(static_cast<uint16_t>(b - a) << 2);
    return static_cast<int16_t>(static_cast<int16_t>(d) >> 2);
}

// The filtered speed in q8 (|y| <= 2^21): the upper three bytes of acc.
PORT_INLINE int32_t spd_q8(const spd_state* s) {
    return s->acc >> 8;
}

// x / ticks rounded towards zero for ticks 1..3 (the span of one delta after missed samples),
// without a division. |x| < 2^31.
int32_t spd_div_ticks(int32_t x, uint8_t ticks);

// The delta of a sample after missed ticks, in q8 (rare path, out of line).
int32_t spd_gap_q8(spd_state* s, int16_t delta);

// Feed one good angle (14 bits; upper bits ignored) with the filter gain k of spd_gain(). Inline:
// it runs for every wheel in every control step.
PORT_INLINE void spd_update(spd_state* s, uint16_t angle14, uint8_t k) {
    angle14 = static_cast<uint16_t>(angle14 & 0x3FFFu);
    if (!s->primed) {
        s->primed = 1;
        s->missed = 0;
        s->last_angle = angle14;
        return;
    }
    int16_t delta = spd_wrap_delta(s->last_angle, angle14);
    s->last_angle = angle14;
    int32_t x = s->missed ? spd_gap_q8(s, delta) : static_cast<int32_t>(delta) * SPD_Q8_PER_COUNT;
    if (k == 0) {
        s->acc = x * 256;  // shift 0: the raw delta
    } else {
        s->acc += port_mul_s24_u8(x - spd_q8(s), k);
    }
}

// The sample of this tick was bad: hold the estimate, the next good sample spans the gap.
void spd_skip(spd_state* s);

// n control ticks passed without a step (main-loop overrun): the next good sample spans them too,
// so its delta is divided by the true number of elapsed ticks. A span of more than 3 ticks
// re-primes (estimate held for one sample), as after 3 bad samples.
void spd_missed_ticks(spd_state* s, uint8_t n);

// Protocol boundary. q8 -> mrad/s: * 383.496 / 256 (98175 / 65536, relative error 3e-6), rounded
// towards zero; |q8| <= 2^22. mrad/s -> q8: * 43748 / 65536 (relative error 4e-6: 1.6 mrad/s at
// the 400 rad/s limit), rounded towards zero; |mrad/s| <= 2^22.
int32_t spd_q8_to_mrad_s(int32_t q8);
int32_t spd_mrad_s_to_q8(int32_t mrad_s);

#endif  // SPEED_H
