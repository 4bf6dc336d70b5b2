// app.h - the wheel-board application: control step of four wheels, message dispatcher,
// telemetry and fail-safes. Portable: the board layer feeds it encoder words, received bytes and
// tick events, and applies the PWM compare values and enable mask it produces.
#ifndef APP_H
#define APP_H

#include <stdint.h>

#include "cal.h"
#include "commut.h"
#include "fault.h"
#include "guard.h"
#include "pi.h"
#include "params.h"
#include "proto.h"
#include "speed.h"

#define APP_WHEELS 4
#define APP_TICK_HZ 1000

// Stopping in closed loop: when a running wheel's ramped setpoint and target reach 0 (STOP_ALL,
// fail-safe, SET_SPEEDS 0), the loop keeps driving (braking towards 0) until the wheel has
// stopped, then disables the wheel's driver. Stopped is judged on the encoder's angles, not on the
// filtered estimate: the filter lags a braking wheel by a few rad/s, so braking until it read zero
// drove the wheel backwards. The test: the angle change over the last APP_STOP_WINDOW ticks, D,
// signed in the direction being braked (the sign of the lagging estimate), below APP_STOP_WINDOW *
// APP_STOP_Q8 (334 q8 = 1.3 counts per tick = 0.50 rad/s = 4.8 rpm, as a mean over the window);
// a wheel that reversed shows a D below it as well. A window with a bad encoder word at either end
// is not judged.
// Why a window of 4: the AS5048A reads with about 2 counts rms of noise (sigma), so any change of
// two reads has sqrt(2) * 2 = 2.83 counts rms, over one tick or over N. On one tick's change
// against 1.3 counts that let a wheel go at up to 1.3 + 4 * 2.83 = 12.6 counts a tick (4.8 rad/s)
// at 4 sigma; over N ticks the mean speed at release is at most (1.3 * N + 4 * 2.83) / N counts a
// tick: 4.1 (1.58 rad/s) for N = 4. The window's price is its lag: braking at a counts per tick^2
// the window's mean runs a * N / 2 ahead of the present speed, and the brake holds until the mean
// is below 1.3. At the strongest braking of the motor (275 rad/s^2 at full drive, 0.72 counts per
// tick^2) that is 1.43 counts a tick for N = 4: without noise the wheel is released before it
// turns backwards faster than 1.3 - 1.43 = -0.13 counts a tick (0.05 rad/s; at the default DECEL
// of 200 rad/s^2 it is still turning forwards at 0.26). N = 6 would bound the release at
// 1.42 rad/s but allow 0.22 rad/s backwards; 4 is a power of two (the ring's index is a mask).
// APP_STOP_TICKS (500 ms) bounds a wheel that cannot be stopped (a load, a frozen encoder); a
// wheel already off stays off.
#define APP_STOP_Q8 334L
#define APP_STOP_WINDOW 4u  // power of two
#define APP_STOP_TICKS 500u
#define APP_NO_ANGLE 0xFFFFu  // no angle in a brake_angles slot (angles are 14 bits)

// Open loop (MODE 1) is a bench mode with nothing measuring the rotor: a SET_SPEEDS there drives
// at OPEN_LOOP_DRIVE_Q15, capped at DRIVE_MAX_Q15 (the closed loop's own limit), under the
// heartbeat as in closed loop, and for at most APP_OPEN_LOOP_MS while any wheel runs; then
// OPEN_LOOP_LIMIT latches and the wheels ramp to 0 at DECEL. 10 s: a locked rotor at half supply
// (the default cap: a 3.45 V vector, about 1.2 W into a 10 Ohm winding) takes 12 J, about 0.3 K
// for the motor's 100 g. MODE 1 is never restored at boot: each session enables it.
#define APP_OPEN_LOOP_MS 10000u
#define APP_NO_WHEEL 0xFFu  // cal_wheel: no calibration running

// Enqueue one whole frame for transmission; false if it does not fit (the frame is dropped).
typedef bool (*app_tx_fn)(const uint8_t* data, uint8_t len);

struct app_counters {
    uint16_t bad_crc;
    uint16_t short_frame;
    uint16_t oversize;
    uint16_t bad_cobs;
    uint16_t unknown_id;
    uint16_t bad_length;
    uint16_t tx_dropped;
    uint16_t tick_overruns;
    uint16_t rx_overflow;
    uint16_t step_max_us;
};

// Speeds inside the control step are q8 (encoder counts per tick * 256, speed.h); mrad/s only at
// the protocol boundary (setpoints, ramp, telemetry).
struct app_wheel {
    spd_state spd;
    pi_state pi;
    int32_t sp_q8;          // sp_mrad_s in q8, fed to the controller
    int32_t target_mrad_s;  // accepted setpoint
    int32_t sp_mrad_s;      // ramped setpoint
    uint32_t ol_phase;      // open-loop electrical phase, 2^32 = one turn
    int16_t drive_q15;      // signed drive level
    uint16_t stop_ticks;    // ticks braking at setpoint 0 (APP_STOP_TICKS)
    // Encoder angles of the last APP_STOP_WINDOW braking ticks, a ring indexed by stop_ticks;
    // APP_NO_ANGLE for a tick with a bad word.
    uint16_t brake_angles[APP_STOP_WINDOW];
    grd_wheel grd;  // sensor and motion supervision
};

// Parameters in the form the control step uses them, derived from prm.v once per change so that
// the 1 kHz step converts nothing. A PARAM_SET only marks them stale (ctl_stale): app_derive_ctl
// derives them (about 1,750 cycles: a 32-bit division, four speed conversions), which the board
// runs as two jobs after the next step, outside step_max_us, and a burst of them once a tick. The
// new value takes effect in the ramp and the step of the tick after. MODE and POLE_PAIRS (accepted
// only with the drivers off), app_init, PARAM_DEFAULTS and the calibration derive at once.
enum : uint8_t { APP_CTL_FRESH, APP_CTL_STALE, APP_CTL_HALF };  // app_state.ctl_stale
struct app_ctl {
    pi_gains gains;
    cmt_lead lead;
    int32_t accel;  // ramp step per tick, mrad/s
    int32_t decel;
    uint16_t enc_offset[APP_WHEELS];
    uint16_t heartbeat_ms;
    int16_t open_loop_drive;
    grd_limits grd;
    uint8_t closed;     // 1 closed loop on the encoders, 0 open loop
    uint8_t loop_mask;  // bit w: the speed loop drives wheel w (closed loop, not calibrating)
    uint8_t pole_pairs;
    uint8_t spd_k;  // speed filter gain, spd_gain(SPEED_FILTER_SHIFT)
    uint8_t enc_fault_limit;
};

// A telemetry frame in the making (app_telemetry_begin, app_telemetry_work): raw is the id, the
// payload and the CRC; the speeds are taken as the step left them (q8 in closed loop) and
// converted to mrad/s in a later slice.
#define APP_TELEM_RAW (1 + PROTO_LEN_TELEMETRY + 2)
struct app_telem {
    uint8_t stage;    // next slice (APP_TELEM_*), APP_TELEM_IDLE when no frame is in the making
    uint8_t convert;  // the speeds are q8 (closed loop), not yet mrad/s
    uint8_t raw[APP_TELEM_RAW];
    uint8_t wire[COBS_ENCODED_SIZE(APP_TELEM_RAW) + 1];
};

// A reply held for two jobs of its own (app_reply_work: the CRC, then the COBS and the copy into
// the TX ring), which would otherwise make a frame's dispatch the main loop's longest job. The
// longest reply payload is STATS.
#define APP_REPLY_MAX PROTO_LEN_STATS
enum : uint8_t { APP_REPLY_NONE, APP_REPLY_CRC, APP_REPLY_SEND };
struct app_reply {
    uint8_t stage;  // APP_REPLY_*: none waits, its CRC next, its COBS and queueing next
    uint8_t body;   // id and payload bytes in raw
    uint8_t raw[1 + APP_REPLY_MAX + 2];
};

struct app_state {
    app_wheel w[APP_WHEELS];
    app_ctl ctl;
    prm_store prm;
    flt_state flt;
    proto_rx rx;
    app_counters cnt;
    app_tx_fn tx;
    uint16_t seq;
    uint8_t telem_count;
    uint8_t stopping;             // STOP_ALL in progress: ramp with DECEL
    uint8_t stops_seen;           // STOP_ALL frames the receive interrupt saw (free-running)
    uint8_t stops_dispatched;     // STOP_ALL frames dispatched (free-running)
    uint16_t pwm[APP_WHEELS][3];  // compare values 0..CMT_PWM_TOP
    uint8_t enable_mask;          // bit w: driver stage of wheel w enabled
    // Bit w: ramped setpoint or target of wheel w nonzero (app_update_run_mask, wherever either
    // changes), so that the step tests one bit instead of two 32-bit values per wheel.
    uint8_t run_mask;
    // Bit w: encoder w answered a bad word (error flag or parity) in this step; the board sends it
    // ENC_CMD_CLEAR_ERROR after the step, whose reply (the error register) comes in the next
    // step's command frame and is not used.
    uint8_t enc_clear;
    // Bit w: wheel w's ENC_OFFSET is a default (PARAMS_DEFAULTED at boot, PARAM_DEFAULTS) and was
    // neither set nor calibrated since: closed-loop setpoints other than 0 are refused.
    uint8_t uncal_mask;
    uint8_t cal_wheel;  // wheel being calibrated (CALIBRATE_ENC), or APP_NO_WHEEL
    uint8_t diag_next;  // wheel whose diagnostics register is read next
    uint8_t ctl_stale;  // APP_CTL_*: prm.v changed since ctl was derived (app_ctl)
    uint16_t open_ms;   // ticks open loop has driven a wheel without a stop (APP_OPEN_LOOP_MS)
    cal_state cal;
    app_telem tm;
    // A received frame (or a decoding error) that app_rx_decode completed and app_rx_act has not
    // acted on yet; rx_frame's payload points into rx.buf, which stays intact until then.
    uint8_t rx_result;  // proto_rx_result, PROTO_RX_NONE when nothing waits
    proto_frame rx_frame;
    app_reply reply;
};

// boot_faults: PROTO_FAULT_* bits known at start-up (e.g. WATCHDOG_RESET).
void app_init(app_state* a, const prm_eeprom_if* ee, app_tx_fn tx, uint16_t boot_faults);

// Received bytes in three jobs, so that the board can run a control step between a frame's
// COBS (at its delimiter), its CRC and checks, and its dispatch: app_rx_decode feeds one byte and
// returns true when a frame or an error waits for app_rx_act; then call app_rx_act while
// app_rx_waits, and feed no byte until it is false. Inline: a byte inside a frame is one store,
// without the call and its stack frame.
bool app_rx_decode_end(app_state* a, uint8_t byte);
inline bool app_rx_decode(app_state* a, uint8_t byte) {
    return !proto_rx_append(&a->rx, byte) && app_rx_decode_end(a, byte);
}
inline bool app_rx_waits(const app_state* a) {
    return a->rx_result != PROTO_RX_NONE;
}
void app_rx_act(app_state* a);
// One part of the reply the dispatch (or the tick's work) left in a->reply: its CRC, then its COBS
// and the copy into the TX ring. False when none was left. The board runs them as jobs before the
// next frame's; app_rx_byte right away.
bool app_reply_step(app_state* a);
inline bool app_reply_work(app_state* a) {
    return a->reply.stage != APP_REPLY_NONE && app_reply_step(a);
}
// All at once: a complete frame is dispatched and answered as its delimiter is fed (native tests,
// fuzzing).
inline void app_rx_byte(app_state* a, uint8_t byte) {
    if (!app_rx_decode(a, byte)) return;
    while (app_rx_waits(a)) app_rx_act(a);
    while (app_reply_work(a)) {
    }
}

// STOP_ALL's action: every target to 0, ramped down with DECEL. The dispatcher calls it (and
// acknowledges the frame).
void app_stop_all(app_state* a);

// STOP_ALL acted on before its turn: the board's receive interrupt counts the STOP_ALL frames it
// recognises (free-running), and the main loop passes the count here once per tick. A count
// ahead of the STOP_ALLs dispatched stops the wheels now, not behind the frames queued before it.
// Those frames are still dispatched in order, except SET_SPEEDS: sent before the stop, they are
// dropped until the STOP_ALL itself is dispatched (and acknowledged). Counts, not a flag: a
// STOP_ALL dispatched before the main loop read the count is not acted on again (that would
// cancel a SET_SPEEDS sent after it) and never leaves setpoints dropped.
void app_note_stops_seen(app_state* a, uint8_t stops_seen);

// Background work of the main loop (EEPROM save progress). The test inline: the board's main
// loop passes here on every idle or decoding pass, and a call with its register saves there cost
// more of the CPU than a SET_SPEEDS stream leaves (reports/firmware-timing.md).
void app_poll_save(app_state* a);
inline void app_poll(app_state* a) {
    if (a->prm.saving) app_poll_save(a);
}

// One 1 ms control step of all wheels. enc_words: the AS5048A reply words (ignored in open loop).
// Runs the step (app_step.h), app_derive_ctl, app_setpoints_tick and app_supervise of every
// wheel, as the board does every tick.
void app_control_step(app_state* a, const uint16_t enc_words[APP_WHEELS]);

// The parameters a PARAM_SET left stale derived (app_ctl), in two halves of about 900 cycles:
// the drive's, then the supervision's. One half a call; true when the second is left.
bool app_derive_ctl(app_state* a);

// Setpoint work of a tick, after its control step (not in the control law's latency): heartbeat
// supervision, targets to 0 on the fail-safe or an encoder fault, the ramp (DECEL while stopping).
void app_setpoints_tick(app_state* a);

// Sensor and motion supervision of wheel i after the tick's step (guard.h), in closed loop: faults
// latch for the next step. The board runs it after the step's time is taken (about 375 cycles a
// wheel: not part of step_max_us), one wheel a job.
void app_supervise(app_state* a, uint8_t i);

// Diagnostics registers, read round robin in the tick's spare time after the step: the wheel
// whose register to read now (APP_WHEELS: none, open loop), then its reply word.
uint8_t app_diag_wheel(app_state* a);
void app_diag_result(app_state* a, uint8_t wheel, uint16_t word);

// Telemetry in slices, so that no part of a frame delays a control step by more than one slice
// (the board runs the next step between them): app_telemetry_begin takes the tick's values if
// this tick is due (TELEMETRY_DIV; t_us: time stamp of the step) and a frame is not still in the
// making; each app_telemetry_work does one slice (speed conversions, CRC, COBS, queueing) and
// returns false when no slice was left. app_telemetry does both at once.
void app_telemetry_begin(app_state* a, uint32_t t_us);
bool app_telemetry_work(app_state* a);
void app_telemetry(app_state* a, uint32_t t_us);

// Board events. app_note_overrun: missed_ticks control ticks passed without a step (the tick
// ISR counts them); call it before the step that follows them.
void app_note_overrun(app_state* a, uint8_t missed_ticks);
// app_note_rx_overflow: bytes were lost; stops_seen as for app_note_stops_seen (a STOP_ALL seen in
// the lost bytes still stops; setpoints are not held off waiting for a frame that may be gone).
void app_note_rx_overflow(app_state* a, uint8_t stops_seen);
void app_note_step_time(app_state* a, uint16_t us);

uint8_t app_status(const app_state* a);

// Speed of wheel i in mrad/s as telemetry reports it: measured (closed loop) or commanded (open
// loop).
int32_t app_speed_mrad_s(const app_state* a, uint8_t i);

#endif  // APP_H
