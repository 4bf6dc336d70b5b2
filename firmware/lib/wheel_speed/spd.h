// spd.h - fixed-point wheel speed estimator from 14-bit encoder angles sampled at the control tick.
//
// Speed unit everywhere: mrad/s in int32 (3000 rpm = 314159 mrad/s). One encoder count per 1 ms
// tick is 2*pi/16384 rad/ms = 383.495 mrad/s; the conversion uses 98175 / 256 = 383.496 (relative
// error 3e-6). Angle differences are wrapped at 14 bits, so a delta is unambiguous up to
// +-8191 counts per tick (30000 rpm).
// Filter: first-order low pass y += (x - y) / 2^shift, kept as acc = y * 2^shift so that a constant
// input gives exactly that output. shift = 0 disables filtering. |acc| <= 8192 * 383.5 * 2^8 <
// 2^31.
#ifndef SPD_H
#define SPD_H

#include <stdint.h>

#include "port_progmem.h"

#define SPD_TICK_HZ 1000
#define SPD_MAX_SHIFT 8

struct spd_state {
    int32_t acc;           // filtered speed * 2^shift, mrad/s
    int32_t speed_mrad_s;  // filtered speed, mrad/s
    uint16_t last_angle;   // last good 14-bit angle
    uint8_t primed;        // 0 until the first good angle
    uint8_t missed;        // ticks since the last good angle, minus one
    uint8_t shift;         // filter shift of the last update: speed_mrad_s == acc >> shift
};

void spd_init(spd_state* s);

// Signed difference b - a of two 14-bit angles, wrapped into [-8192, 8191] counts.
int16_t spd_wrap_delta(uint16_t a, uint16_t b);

// Counts per tick to mrad/s (symmetric rounding towards zero).
PORT_INLINE int32_t spd_counts_to_mrad_s(int16_t counts_per_tick) {
    // 383.496 mrad/s per count per 1 ms tick, times 256: 98175 = 65536 + 32639, so the product
    // is one 16 x 16 -> 32 multiply plus the magnitude moved up 16 bits; |c| * 98175 < 2^32 for
    // every int16 (the magnitude of -32768 is 32768 as uint16).
    uint16_t mag = static_cast<uint16_t>(counts_per_tick);
    if (counts_per_tick < 0) mag = static_cast<uint16_t>(0u - mag);
    uint32_t p = (static_cast<uint32_t>(mag) << 16) + port_mul_u16(mag, 32639u);
    int32_t v = static_cast<int32_t>(p >> 8);
    return counts_per_tick < 0 ? -v : v;
}

// x / ticks rounded towards zero for ticks 1..3 (the span of one delta after missed samples),
// without a division. |x| < 2^31.
int32_t spd_div_ticks(int32_t x, uint8_t ticks);

// Feed one good angle; returns the filtered speed in mrad/s. shift is clamped to SPD_MAX_SHIFT.
int32_t spd_update(spd_state* s, uint16_t angle14, uint8_t shift);

// The sample of this tick was bad: hold the estimate, the next good sample spans the gap.
void spd_skip(spd_state* s);

#endif  // SPD_H
