// cal.h - electrical zero of one wheel found with its own motor (CALIBRATE_ENC), the idea of
// SimpleFOC's sensor alignment: the field is held at electrical angle 0 with the limited
// open-loop drive until the rotor has settled (CAL_ALIGN_TICKS), turned one electrical turn
// forwards and one back (CAL_SWEEP_TICKS each), and held again (CAL_SETTLE_TICKS). Then:
//   moved   = encoder angle after the forward turn - angle after the first hold; it must be
//             1/POLE_PAIRS of a turn within a quarter of that (else NOT_MOVED below a quarter,
//             REVERSED if negative, POLE_PAIRS otherwise), and the turn back must return it;
//   offset  = the mean of the two held angles as an electrical angle (mech * 4 * pole_pairs mod
//             2^16): the ENC_OFFSET that makes cmt_elec_angle read 0 where the field at 0 holds
//             the rotor (cmt_phases puts the vector at its angle; closed loop drives it at the
//             rotor angle + 90 degrees).
// One electrical turn must be below half a mechanical turn (angle differences wrap at 14 bits):
// POLE_PAIRS >= 3, else POLE_PAIRS fails at once.
// Portable: the application feeds the encoder angle every tick and drives the field at
// cal_state.field with OPEN_LOOP_DRIVE.
#ifndef CAL_H
#define CAL_H

#include <stdint.h>

#define CAL_ALIGN_TICKS 500u
#define CAL_SWEEP_TICKS 512u  // 65536 / 512 = 128 angle units per tick: one electrical turn
#define CAL_SETTLE_TICKS 250u
#define CAL_FIELD_STEP 128u
#define CAL_TOTAL_TICKS (CAL_ALIGN_TICKS + 2u * CAL_SWEEP_TICKS + CAL_SETTLE_TICKS)

enum cal_phase : uint8_t {
    CAL_ALIGN = 0,
    CAL_FORWARD = 1,
    CAL_BACK = 2,
    CAL_SETTLE = 3,
};

enum cal_outcome : uint8_t {
    CAL_RUNNING = 0,  // call cal_tick again next tick
    CAL_DONE = 0xFF,  // *offset16 holds the result; other values: a PROTO_CAL_* reason
};

struct cal_state {
    uint16_t field;  // electrical angle of the field for the next tick, turn/65536
    uint16_t ticks;  // ticks spent in the phase
    uint16_t a0;     // angle after the first hold
    uint16_t a1;     // angle after the forward turn
    uint8_t phase;
    uint8_t pole_pairs;
};

void cal_begin(cal_state* c, uint8_t pole_pairs);

// One tick with the wheel's latest good 14-bit encoder angle; returns CAL_RUNNING, CAL_DONE (with
// *offset16 set) or the PROTO_CAL_* reason of a failure.
uint8_t cal_tick(cal_state* c, uint16_t angle, uint16_t* offset16);

#endif  // CAL_H
