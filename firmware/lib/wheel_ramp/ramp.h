// ramp.h - setpoint ramp: moves a speed setpoint towards its target by at most step per tick.
// Speeds in mrad/s; at the 1 kHz tick a step of N mrad/s per tick is an acceleration of N rad/s^2.
#ifndef RAMP_H
#define RAMP_H

#include <stdint.h>

// Returns the new value; step <= 0 is treated as 1 so a ramp always converges.
int32_t ramp_step(int32_t value, int32_t target, int32_t step);

#endif  // RAMP_H
