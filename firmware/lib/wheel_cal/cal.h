// cal.h - electrical zero of one wheel found with its own motor (CALIBRATE_ENC), the idea of
// SimpleFOC's sensor alignment: the field, at the limited OPEN_LOOP_DRIVE, is held at electrical
// angle 0 (CAL_ALIGN), turned one electrical turn forwards (CAL_FORWARD), held (CAL_HOLD),
// turned back (CAL_BACK) and held again (CAL_SETTLE). The forward turn must have moved the rotor
// forwards by at least a quarter of 1/POLE_PAIRS turn (else NOT_MOVED, or REVERSED if backwards).
// A rotor held by the field swings about its rest angle (a gimbal motor on a resistive winding is
// lightly damped), so from then on the field put out is moved against the rotor's motion of the
// last tick (CAL_DAMP_PER_COUNT per count: a damping torque, which only works once the direction
// is known), and each hold takes the mean angle of its last CAL_MEAN_TICKS. The turn back between
// the two damped holds must be one electrical turn within a quarter (else POLE_PAIRS). The offset
// is the last hold's angle as an electrical angle (mech * 4 * pole_pairs mod 2^16): the
// ENC_OFFSET that makes cmt_elec_angle read 0 where the field at 0 holds the rotor (cmt_phases
// puts the vector at its angle; the closed loop drives it at the rotor angle + 90 degrees).
// One electrical turn must be below half a mechanical turn (angle differences wrap at 14 bits):
// POLE_PAIRS >= 3, else POLE_PAIRS fails at once.
// Portable: the application feeds the encoder angle every tick and drives the field at
// cal_state.out with OPEN_LOOP_DRIVE.
#ifndef CAL_H
#define CAL_H

#include <stdint.h>

#define CAL_HOLD_TICKS 600u
#define CAL_MEAN_SHIFT 8
#define CAL_MEAN_TICKS (1u << CAL_MEAN_SHIFT)
#define CAL_SWEEP_TICKS 512u  // 65536 / 512 = 128 angle units per tick: one electrical turn
#define CAL_FIELD_STEP 128u
#define CAL_DAMP_PER_COUNT 1500  // field angle units (turn/65536) per count per tick
#define CAL_DAMP_MAX_COUNTS 10   // clamp: 83 degrees electrical
#define CAL_TOTAL_TICKS (3u * CAL_HOLD_TICKS + 2u * CAL_SWEEP_TICKS)  // 2.8 s

enum cal_phase : uint8_t {
    CAL_ALIGN = 0,
    CAL_FORWARD = 1,
    CAL_HOLD = 2,
    CAL_BACK = 3,
    CAL_SETTLE = 4,
};

enum cal_outcome : uint8_t {
    CAL_RUNNING = 0,  // call cal_tick again next tick
    CAL_DONE = 0xFF,  // *offset16 holds the result; other values: a PROTO_CAL_* reason
};

struct cal_state {
    uint16_t field;       // the program's field angle, turn/65536
    uint16_t out;         // the field to put out for the next tick (field, damped)
    uint16_t prev_angle;  // the angle of the last tick
    uint16_t ticks;       // ticks spent in the phase
    int32_t sum;          // angles of the hold's mean, relative to ref (counts)
    uint16_t ref;         // first angle of the hold's mean
    uint16_t a0;          // angle at the end of the first hold
    uint16_t a1;          // mean angle of the hold after the forward turn
    uint8_t phase;
    uint8_t pole_pairs;
};

void cal_begin(cal_state* c, uint8_t pole_pairs);

// One tick with the wheel's latest good 14-bit encoder angle; returns CAL_RUNNING, CAL_DONE (with
// *offset16 set) or the PROTO_CAL_* reason of a failure.
uint8_t cal_tick(cal_state* c, uint16_t angle, uint16_t* offset16);

#endif  // CAL_H
