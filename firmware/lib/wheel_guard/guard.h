// guard.h - sensor and motion supervision of one wheel, run once per control tick after the step
// (out of the control law's latency) and once per diagnostics read:
//   stuck word: the encoder reads 0x0000 or 0x3FFF (MISO stuck low or high with a valid-looking
//     word) unchanged for dead_ticks (ENC_FAULT_LIMIT) ticks while the wheel is driven at half
//     DRIVE_MAX or more: ENC_STUCK. Any other word frozen under drive reads as a stopped rotor:
//     the stall below (the board cannot tell a frozen sensor from a blocked rotor; a real
//     AS5048A's noise of about 2 counts rms moves the word of a rotor at rest);
//   diagnostics: the AS5048A's diagnostics register (0x3FFD) bad in GRD_DIAG_LIMIT consecutive
//     reads: offset compensation not finished, CORDIC overflow, magnet too strong or too weak,
//     or the reply itself broken (parity, error flag): ENC_DIAG;
//   stall: the closed loop's drive saturated at half DRIVE_MAX or more with |speed| below
//     STALL_SPEED, and the speed not changed by STALL_SPEED, for fault_ticks: STALL;
//   runaway: while the loop drives the wheel, for fault_ticks, the speed against the setpoint's
//     sign by more than RUNAWAY_MARGIN without coming closer to the setpoint, or above
//     SPEED_MAX + RUNAWAY_MARGIN: RUNAWAY.
// The functions return the PROTO_FAULT_* bits to latch (0: none); the application latches them.
#ifndef GUARD_H
#define GUARD_H

#include <stdint.h>

// Diagnostics register (AS5048A datasheet, "Diagnostics + Automatic Gain Control"): bits 7..0
// AGC, 8 OCF (offset compensation finished: must be 1), 9 COF (CORDIC overflow), 10 COMP_LOW
// (magnet too strong), 11 COMP_HIGH (magnet too weak).
#define GRD_DIAG_OCF 0x0100u
#define GRD_DIAG_BAD 0x0E00u  // COF | COMP_LOW | COMP_HIGH
// Read of register 0x3FFD: bit 14 read, bit 15 even parity (0x3FFD | 0x4000 has 14 set bits).
#define GRD_CMD_READ_DIAG 0x7FFDu
#define GRD_DIAG_LIMIT 2  // consecutive bad diagnostics reads that latch (8 ms apart per wheel)

struct grd_limits {
    int16_t drive_min_q15;  // |drive| at or above this counts as driven hard (DRIVE_MAX / 2)
    uint16_t fault_ticks;   // MOTION_FAULT_MS
    uint8_t dead_ticks;     // ENC_FAULT_LIMIT: a stuck 0x0000 / 0x3FFF word
    int32_t stall_q8;       // STALL_SPEED in q8
    int32_t margin_q8;      // RUNAWAY_MARGIN in q8
    int32_t over_q8;        // SPEED_MAX + RUNAWAY_MARGIN in q8
};

struct grd_wheel {
    uint16_t prev_angle;
    uint16_t same_ticks;
    uint16_t stall_ticks;
    uint16_t runaway_ticks;
    uint16_t over_ticks;
    int32_t stall_from_q8;    // speed when the stall episode began
    int32_t runaway_from_q8;  // speed when the runaway episode began
    uint8_t diag_bad;
};

void grd_reset(grd_wheel* g);

// The encoder angle of this tick. fresh: angle is this tick's good word; driven: the wheel's
// driver is enabled with |drive| >= drive_min_q15.
uint16_t grd_sensor(grd_wheel* g, const grd_limits* l, uint16_t angle, bool fresh, bool driven);

// One tick of the closed loop. looping: the speed loop drives the wheel this tick; saturated:
// its drive is held by the output or slew limit; speed and setpoint in q8.
uint16_t grd_motion(grd_wheel* g, const grd_limits* l, bool looping, bool saturated,
                    int16_t drive_q15, int32_t speed_q8, int32_t sp_q8);

// One reply word of a diagnostics register read.
uint16_t grd_diag(grd_wheel* g, uint16_t word);

#endif  // GUARD_H
