// app_step.h - the 1 kHz control step of four wheels, written for the AVR: one loop over the
// wheels walking pointers (no index arithmetic), the hot path (encoder word, estimator, PI, lead,
// commutation) inline, the rare paths (ramp, open loop, wheel off) out of line. Speeds are q8
// (speed.h) inside the step; mrad/s only at the protocol boundary.
//
// The step is a template over the encoder reads (Io) so that the board layer can overlap the SPI
// transfers of encoder i+1 with the arithmetic of wheel i without the portable logic touching a
// register:
//   uint16_t first()        the reply word of encoder 0 (the board reads it at once);
//   void next(uint8_t k)    stage k (0..APP_IO_STAGES-1) of reading the next encoder, called at
//                           fixed points of the wheel's arithmetic, at least ~40 cycles apart;
//   uint16_t word(uint8_t i) the reply word of encoder i >= 1 (after all stages of wheel i - 1).
// app_control_step (app.h) runs it on words given up front, then app_setpoints_tick.
// The setpoints (heartbeat supervision, fail-safe, ramp) are not part of the step: the board runs
// app_setpoints_tick after it, so the step of tick k works on the setpoints ramped in tick k - 1.
#ifndef APP_STEP_H
#define APP_STEP_H

#include "app.h"
#include "commut.h"
#include "enc.h"
#include "fault.h"
#include "pi.h"
#include "speed.h"

#define APP_IO_STAGES 5

// Rare paths of the step (app.cpp).
void app_wheel_off(app_wheel* w, uint16_t pwm[3]);
void app_wheel_open(const app_ctl* c, app_wheel* w, uint16_t pwm[3]);
// Setpoint and target at 0 in closed loop: true while the wheel (enabled in the last tick) still
// turns at APP_STOP_Q8 or more in the direction being braked, measured on the encoder's angle
// change over the last APP_STOP_WINDOW ticks (app.h), and APP_STOP_TICKS have not passed; the
// loop then brakes on.
bool app_brake_on(app_wheel* w, bool was_enabled);

// One wheel of the step, I its constant index (the step calls it four times): with a constant
// index and, on AVR, the state at a constant address (main.cpp passes &g_app and the step is
// inlined there), every field is a fixed address (lds/sts) and no pointer or counter lives in
// the stack frame across the calls into the PI and the commutation.
template <uint8_t I, class Io>
PORT_INLINE void app_wheel_step(app_state* a, Io& io, uint8_t& enable, uint16_t& word) {
    const uint8_t bit = static_cast<uint8_t>(1u << I);
    if (I != 0) word = io.word(I);
    io.next(0);
    app_wheel* w = &a->w[I];
    const app_ctl* c = &a->ctl;
    const bool closed = c->closed;
    bool disabled = false;
    if (closed) {
        // Error flag first (one bit test of the high byte), then the parity.
        const bool good = !(static_cast<uint8_t>(word >> 8) & 0x40u) && enc_even_parity(word);
        disabled = flt_encoder_sample(&a->flt, &a->flt.enc_bad[I], bit, good, c->enc_fault_limit);
        if (good) {
            spd_update(&w->spd, word, c->spd_k);
        } else {
            spd_skip(&w->spd);
            a->enc_clear |= bit;  // clear the sensor's error flag after the step
        }
    }
    io.next(1);
    uint16_t* pwm = a->pwm[I];
    const bool run = a->run_mask & bit;
    const bool loop = c->loop_mask & bit;  // 0 in open loop and while calibrating (cal.h)
    if (disabled || !loop || (!run && !app_brake_on(w, a->enable_mask & bit))) {
        if (!disabled && !loop && run) {
            app_wheel_open(c, w, pwm);
            enable |= bit;
        } else {
            app_wheel_off(w, pwm);
        }
        io.next(2);
        io.next(3);
    } else {
        io.next(2);
        // The error in q8 speed units (the gains are per q8 unit): no conversion.
        const int16_t drive = pi_step_err(&w->pi, &c->gains, w->sp_q8 - spd_q8(&w->spd));
        w->drive_q15 = drive;
        io.next(3);
        // Electrical angle advanced by speed * lead (sensor-to-PWM delay and half a tick),
        // the torque-producing vector 90 degrees ahead of (or behind) the rotor.
        // The speed read again rather than kept across the PI (which clobbers r3..r17): three
        // loads instead of a spill to the stack frame and its reloads.
        cmt_drive(w->spd.last_angle, spd_q8(&w->spd), drive, c->enc_offset[I], &c->lead, pwm);
        enable |= bit;
    }
    io.next(4);
}

// The four wheels one after the other (unrolled: constant indices). Inline on AVR so that the
// board's call with &g_app makes every address a constant.
template <class Io>
PORT_INLINE void app_control_step_io(app_state* a, Io& io) {
    uint8_t enable = 0;
    a->enc_clear = 0;
    uint16_t word = io.first();
    app_wheel_step<0>(a, io, enable, word);
    app_wheel_step<1>(a, io, enable, word);
    app_wheel_step<2>(a, io, enable, word);
    app_wheel_step<3>(a, io, enable, word);
    a->enable_mask = enable;
}

#endif  // APP_STEP_H
