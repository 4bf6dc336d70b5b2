// pi.h - PI speed controller in fixed point with anti-windup, output and slew limits.
//
// Units: error e in mrad/s (int32, clamped to +-PI_ERR_CLAMP so that kp * e fits int32);
// output u in Q15 drive level (32767 = full supply voltage amplitude).
// kp_q8: Q15 counts per mrad/s, times 256.  ki_q8: Q15 counts per mrad/s per tick, times 256.
// u = (kp*e)/256 + I/256, I += ki*e each tick. The clamp of e only acts where a sane kp saturates
// the output anyway (65.5 rad/s error).
// Anti-windup: I is clamped to +-out_max*256; while the output or slew limit holds the output in
// the direction the error pushes it, I grows at most to the value that just reaches the limit
// (back-calculation), so it releases at once when the error reverses.
#ifndef PI_H
#define PI_H

#include <stdint.h>

#define PI_ERR_CLAMP 65535L

struct pi_gains {
    int16_t kp_q8;    // 0..32767 (negative gains are not supported)
    int16_t ki_q8;    // 0..32767
    int16_t out_max;  // 0..32767
    int16_t slew;     // max output change per tick, 1..32767
};

struct pi_state {
    int32_t integ;      // integral term times 256
    int16_t out;        // last output, Q15
    uint8_t saturated;  // 1 if the last output was limited
};

void pi_reset(pi_state* s);

int16_t pi_step(pi_state* s, const pi_gains* g, int32_t setpoint, int32_t measured);

#endif  // PI_H
