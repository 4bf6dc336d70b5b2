#include "app.h"

#include "app_step.h"
#include "crc16.h"

#include "ramp.h"

// The slices of a telemetry frame, in order (app_telem.stage).
enum : uint8_t {
    APP_TELEM_IDLE,
    APP_TELEM_SPEEDS_01,
    APP_TELEM_SPEEDS_23,
    APP_TELEM_CRC,
    APP_TELEM_COBS,
    APP_TELEM_QUEUE
};

static uint16_t sat_inc(uint16_t x) {
    return x < 0xFFFFu ? static_cast<uint16_t>(x + 1) : x;
}

// Its own function: the 45-byte wire buffer's stack frame stays out of app_reply_step's early
// exit, which every pass of the board's main loop takes.
__attribute__((noinline)) static void app_reply_queue(app_state* a) {
    app_reply* r = &a->reply;
    uint8_t wire[PROTO_MAX_WIRE];
    const uint8_t n = proto_wire(r->raw, static_cast<uint8_t>(r->body + 2), wire);
    if (!a->tx(wire, n)) a->cnt.tx_dropped = sat_inc(a->cnt.tx_dropped);
}

bool app_reply_step(app_state* a) {
    app_reply* r = &a->reply;
    if (r->stage == APP_REPLY_CRC) {
        proto_seal(r->raw, r->body);
        r->stage = APP_REPLY_SEND;
    } else {
        app_reply_queue(a);
        r->stage = APP_REPLY_NONE;
    }
    return true;
}

// Held for app_reply_work. A reply still held (a calibration ending in the tick's work, a save
// finished, before the main loop ran its jobs) is sent first: replies stay in order.
static void app_send(app_state* a, uint8_t id, const uint8_t* payload, uint8_t len) {
    static_assert(PROTO_LEN_ACK <= APP_REPLY_MAX && PROTO_LEN_ERROR <= APP_REPLY_MAX &&
                      PROTO_LEN_PARAM_VALUE <= APP_REPLY_MAX &&
                      PROTO_LEN_HELLO_REPLY <= APP_REPLY_MAX,
                  "every reply fits the reply slot");
    while (app_reply_work(a)) {
    }
    app_reply* r = &a->reply;
    r->raw[0] = id;
    for (uint8_t i = 0; i < len; i++) r->raw[1 + i] = payload[i];
    r->body = static_cast<uint8_t>(len + 1);
    r->stage = APP_REPLY_CRC;
}

static void app_send_ack(app_state* a, uint8_t req_id) {
    app_send(a, PROTO_ID_ACK, &req_id, 1);
}

static void app_send_error(app_state* a, uint8_t req_id, uint8_t code, uint8_t detail) {
    uint8_t p[PROTO_LEN_ERROR] = {req_id, code, detail};
    app_send(a, PROTO_ID_ERROR, p, sizeof p);
}

static void app_send_param(app_state* a, uint8_t id) {
    uint8_t p[PROTO_LEN_PARAM_VALUE];
    p[0] = id;
    proto_put_i32(&p[1], a->prm.v[id]);
    app_send(a, PROTO_ID_PARAM_VALUE, p, sizeof p);
}

static uint8_t app_cal_bit(const app_state* a) {
    return a->cal_wheel < APP_WHEELS ? static_cast<uint8_t>(1u << a->cal_wheel) : 0;
}

// The calibrated wheel runs open loop at the calibration's field angle (run, not looping).
static void app_update_run_mask(app_state* a) {
    uint8_t m = app_cal_bit(a);
    for (uint8_t i = 0; i < APP_WHEELS; i++) {
        if (a->w[i].sp_mrad_s != 0 || a->w[i].target_mrad_s != 0)
            m |= static_cast<uint8_t>(1u << i);
    }
    a->run_mask = m;
}

static void app_reset_wheel(app_wheel* w) {
    spd_init(&w->spd);
    pi_reset(&w->pi);
    w->sp_q8 = 0;
    w->target_mrad_s = 0;
    w->sp_mrad_s = 0;
    w->ol_phase = 0;
    w->drive_q15 = 0;
    w->stop_ticks = 0;
    grd_reset(&w->grd);
}

// The parameters of the drive (gains, lead, ramp, offsets, heartbeat, mode), then those of the
// supervision (guard.h, the speed filter): two halves, so that a PARAM_SET's derivation is two
// jobs of the board's main loop (app_derive_ctl). The pole pairs only change with a structural
// PARAM_SET (wheels off), PARAM_DEFAULTS or at boot, which derive everything at once
// (app_load_ctl): the lead's division stays out of the halves. All prm.v are within their
// params.def ranges.
static void app_load_poles(app_state* a) {
    app_ctl* c = &a->ctl;
    c->pole_pairs = static_cast<uint8_t>(a->prm.v[PRM_POLE_PAIRS]);
    cmt_lead_poles(&c->lead, c->pole_pairs);
}

static void app_load_drive(app_state* a) {
    const int32_t* v = a->prm.v;
    app_ctl* c = &a->ctl;
    c->gains.kp_q8 = static_cast<uint16_t>(v[PRM_KP]);  // error unit: q8 (speed.h)
    c->gains.ki_q8 = static_cast<uint16_t>(v[PRM_KI]);
    c->gains.out_max = static_cast<int16_t>(v[PRM_DRIVE_MAX_Q15]);
    c->gains.slew = static_cast<int16_t>(v[PRM_SLEW_Q15]);
    c->gains = pi_gains_sanitize(c->gains);
    cmt_lead_time(&c->lead, static_cast<uint16_t>(v[PRM_LEAD_Q8]));
    c->accel = v[PRM_ACCEL_RAD_S2];
    c->decel = v[PRM_DECEL_RAD_S2];
    for (uint8_t i = 0; i < APP_WHEELS; i++) {
        c->enc_offset[i] = static_cast<uint16_t>(v[PRM_ENC_OFFSET_M0 + i]);
    }
    c->heartbeat_ms = static_cast<uint16_t>(v[PRM_HEARTBEAT_MS]);
    const int32_t open_drive =
        v[PRM_OPEN_LOOP_DRIVE_Q15];  // capped at DRIVE_MAX (APP_OPEN_LOOP_MS)
    c->open_loop_drive =
        static_cast<int16_t>(open_drive < c->gains.out_max ? open_drive : c->gains.out_max);
    c->closed = v[PRM_MODE] == 0 ? 1 : 0;
    c->loop_mask = c->closed ? static_cast<uint8_t>(FLT_ALL_WHEELS & ~app_cal_bit(a)) : 0;
}

static void app_load_guard(app_state* a) {
    const int32_t* v = a->prm.v;
    app_ctl* c = &a->ctl;
    grd_limits* g = &c->grd;
    g->drive_min_q15 = static_cast<int16_t>(c->gains.out_max / 2);
    g->fault_ticks = static_cast<uint16_t>(v[PRM_MOTION_FAULT_MS]);
    g->dead_ticks = static_cast<uint8_t>(v[PRM_ENC_FAULT_LIMIT]);
    g->stall_q8 = spd_mrad_s_to_q8(v[PRM_STALL_SPEED_MRAD_S]);
    g->margin_q8 = spd_mrad_s_to_q8(v[PRM_RUNAWAY_MARGIN_MRAD_S]);
    g->over_q8 = spd_mrad_s_to_q8(v[PRM_SPEED_MAX_MRAD_S] + v[PRM_RUNAWAY_MARGIN_MRAD_S]);
    c->spd_k = spd_gain(static_cast<uint8_t>(v[PRM_SPEED_FILTER_SHIFT]));
    c->enc_fault_limit = static_cast<uint8_t>(v[PRM_ENC_FAULT_LIMIT]);
    a->ctl_stale = APP_CTL_FRESH;
}

static void app_load_ctl(app_state* a) {
    app_load_poles(a);
    app_load_drive(a);
    app_load_guard(a);
}

void app_init(app_state* a, const prm_eeprom_if* ee, app_tx_fn tx, uint16_t boot_faults) {
    for (uint8_t i = 0; i < APP_WHEELS; i++) {
        app_reset_wheel(&a->w[i]);
        for (uint8_t k = 0; k < 3; k++) a->pwm[i][k] = 0;
    }
    flt_init(&a->flt);
    proto_rx_init(&a->rx);
    a->reply.stage = APP_REPLY_NONE;
    a->cnt = app_counters();
    a->tx = tx;
    a->seq = 0;
    a->telem_count = 0;
    a->stopping = 0;
    a->enable_mask = 0;
    a->enc_clear = 0;
    a->run_mask = 0;
    a->stops_seen = 0;
    a->stops_dispatched = 0;
    a->cal_wheel = APP_NO_WHEEL;
    a->diag_next = 0;
    a->uncal_mask = 0;
    a->open_ms = 0;
    a->tm.stage = APP_TELEM_IDLE;
    a->rx_result = PROTO_RX_NONE;
    if (!prm_init(&a->prm, ee)) {
        boot_faults |= PROTO_FAULT_PARAMS_DEFAULTED;
        a->uncal_mask = FLT_ALL_WHEELS;
    }
    a->prm.v[PRM_MODE] = 0;  // open loop is enabled per session (APP_OPEN_LOOP_MS)
    app_load_ctl(a);
    flt_set(&a->flt, boot_faults);
}

// ---------------------------------------------------------------- dispatcher

// A STOP_ALL the receive interrupt saw and the dispatcher has not reached yet (counts modulo 256;
// fewer than 128 outstanding).
static bool app_stops_ahead(const app_state* a) {
    return static_cast<int8_t>(a->stops_seen - a->stops_dispatched) > 0;
}

static void app_on_set_speeds(app_state* a, const uint8_t* p) {
    if (app_stops_ahead(a)) return;  // sent before a STOP_ALL that has already stopped the wheels
    if (flt_blocks_setpoints(&a->flt)) {
        app_send_error(a, PROTO_ID_SET_SPEEDS, PROTO_ERR_FAULT_ACTIVE, 0);
        return;
    }
    if (a->cal_wheel != APP_NO_WHEEL) {
        app_send_error(a, PROTO_ID_SET_SPEEDS, PROTO_ERR_BUSY, a->cal_wheel);
        return;
    }
    int32_t vmax = a->prm.v[PRM_SPEED_MAX_MRAD_S];
    int32_t sp[APP_WHEELS];
    for (uint8_t i = 0; i < APP_WHEELS; i++) {
        sp[i] = proto_get_i32(&p[4 * i]);
        if (sp[i] > vmax || sp[i] < -vmax) {  // whole message refused, nothing changes
            app_send_error(a, PROTO_ID_SET_SPEEDS, PROTO_ERR_SETPOINT_ABOVE_MAX, i);
            return;
        }
        if (sp[i] != 0 && a->ctl.closed && (a->uncal_mask & (1u << i))) {
            app_send_error(a, PROTO_ID_SET_SPEEDS, PROTO_ERR_OFFSET_UNCALIBRATED, i);
            return;
        }
    }
    for (uint8_t i = 0; i < APP_WHEELS; i++) a->w[i].target_mrad_s = sp[i];
    a->stopping = 0;
    app_update_run_mask(a);
}

static void app_on_param_set(app_state* a, const uint8_t* p) {
    uint8_t id = p[0];
    int32_t value = proto_get_i32(&p[1]);
    bool structural = (id == PRM_MODE || id == PRM_POLE_PAIRS);
    if ((structural && a->enable_mask) || a->prm.saving) {
        app_send_error(a, PROTO_ID_PARAM_SET, PROTO_ERR_BUSY, id);
        return;
    }
    prm_result r = prm_set(&a->prm, id, value);
    if (r == PRM_UNKNOWN) {
        app_send_error(a, PROTO_ID_PARAM_SET, PROTO_ERR_UNKNOWN_PARAM, id);
    } else if (r == PRM_OUT_OF_RANGE) {
        app_send_error(a, PROTO_ID_PARAM_SET, PROTO_ERR_PARAM_OUT_OF_RANGE, id);
    } else {
        // A structural change resets the wheels (drivers off) and changes what the dispatcher
        // checks (ctl.closed): derived now. Any other waits for the slot after the next step.
        if (structural) {
            app_load_ctl(a);
        } else {
            a->ctl_stale = APP_CTL_STALE;
        }
        if (id >= PRM_ENC_OFFSET_M0 && id <= PRM_ENC_OFFSET_M3) {
            a->uncal_mask &= static_cast<uint8_t>(~(1u << (id - PRM_ENC_OFFSET_M0)));
        }
        if (structural) {
            for (uint8_t i = 0; i < APP_WHEELS; i++) app_reset_wheel(&a->w[i]);
            app_update_run_mask(a);
        }
        app_send_param(a, id);
    }
}

// End the calibration: store the offset (CAL_DONE) and ACK, or answer the failure's reason.
static void app_cal_end(app_state* a, uint8_t outcome, uint16_t offset16) {
    const uint8_t i = a->cal_wheel;
    a->cal_wheel = APP_NO_WHEEL;
    app_reset_wheel(&a->w[i]);
    if (outcome == CAL_DONE) {
        (void)prm_set(&a->prm, static_cast<uint8_t>(PRM_ENC_OFFSET_M0 + i), offset16);
        a->uncal_mask &= static_cast<uint8_t>(~(1u << i));
    }
    app_load_ctl(a);
    app_update_run_mask(a);
    if (outcome == CAL_DONE) {
        app_send_ack(a, PROTO_ID_CALIBRATE_ENC);
    } else {
        app_send_error(a, PROTO_ID_CALIBRATE_ENC, PROTO_ERR_CALIBRATION_FAILED, outcome);
    }
}

static void app_on_calibrate(app_state* a, uint8_t wheel) {
    if (wheel >= APP_WHEELS) {
        app_send_error(a, PROTO_ID_CALIBRATE_ENC, PROTO_ERR_CALIBRATION_FAILED,
                       PROTO_CAL_BAD_WHEEL);
    } else if (flt_blocks_setpoints(&a->flt)) {
        app_send_error(a, PROTO_ID_CALIBRATE_ENC, PROTO_ERR_FAULT_ACTIVE, wheel);
    } else if (!a->ctl.closed || a->enable_mask || a->run_mask || a->prm.saving) {
        app_send_error(a, PROTO_ID_CALIBRATE_ENC, PROTO_ERR_BUSY, wheel);
    } else {
        a->cal_wheel = wheel;  // ACK or ERROR when it ends (app_setpoints_tick)
        cal_begin(&a->cal, a->ctl.pole_pairs);
        app_reset_wheel(&a->w[wheel]);
        app_load_ctl(a);
        app_update_run_mask(a);
    }
}

void app_stop_all(app_state* a) {
    if (a->cal_wheel != APP_NO_WHEEL) app_cal_end(a, PROTO_CAL_INTERRUPTED, 0);
    for (uint8_t i = 0; i < APP_WHEELS; i++) a->w[i].target_mrad_s = 0;
    a->stopping = 1;
    app_update_run_mask(a);
}

void app_note_stops_seen(app_state* a, uint8_t stops_seen) {
    if (stops_seen == a->stops_seen) return;
    a->stops_seen = stops_seen;
    if (app_stops_ahead(a)) app_stop_all(a);
}

static void app_on_simple(app_state* a, uint8_t id) {
    switch (id) {
        case PROTO_ID_STOP_ALL:
            a->stops_dispatched++;
            app_stop_all(a);
            app_send_ack(a, id);
            break;
        case PROTO_ID_PARAM_SAVE:
            if (a->prm.saving) {
                app_send_error(a, id, PROTO_ERR_BUSY, 0);
            } else {
                prm_save_begin(&a->prm);  // ACK when the last byte is written (app_poll)
            }
            break;
        case PROTO_ID_PARAM_DEFAULTS:
            if (a->enable_mask || a->prm.saving) {
                app_send_error(a, id, PROTO_ERR_BUSY, 0);
            } else {
                prm_defaults(&a->prm);
                a->uncal_mask = FLT_ALL_WHEELS;
                app_load_ctl(a);
                for (uint8_t i = 0; i < APP_WHEELS; i++) app_reset_wheel(&a->w[i]);
                app_update_run_mask(a);
                app_send_ack(a, id);
            }
            break;
        default:
            break;
    }
}

static void app_send_hello(app_state* a) {
    uint8_t p[PROTO_LEN_HELLO_REPLY] = {
        PROTO_VERSION, FW_VERSION_MAJOR, FW_VERSION_MINOR, APP_WHEELS, PRM_COUNT, 0, 0};
    proto_put_u16(&p[5], APP_TICK_HZ);
    app_send(a, PROTO_ID_HELLO_REPLY, p, sizeof p);
}

static void app_send_stats(app_state* a) {
    uint8_t p[PROTO_LEN_STATS];
    const uint16_t v[10] = {a->cnt.bad_crc,    a->cnt.short_frame,   a->cnt.oversize,
                            a->cnt.bad_cobs,   a->cnt.unknown_id,    a->cnt.bad_length,
                            a->cnt.tx_dropped, a->cnt.tick_overruns, a->cnt.rx_overflow,
                            a->cnt.step_max_us};
    for (uint8_t i = 0; i < 10; i++) proto_put_u16(&p[2 * i], v[i]);
    app_send(a, PROTO_ID_STATS, p, sizeof p);
}

// Only the frames of the host's control thread keep the wheels alive: a host whose control thread
// died while a poller (GET_STATS, PARAM_GET, HELLO) lives must still lose its heartbeat.
static bool app_is_control_frame(uint8_t id) {
    return id == PROTO_ID_HEARTBEAT || id == PROTO_ID_SET_SPEEDS || id == PROTO_ID_STOP_ALL;
}

// An id not in the table, or one the device only sends: counted and answered UNKNOWN_MESSAGE.
static void app_on_unknown_id(app_state* a, uint8_t id) {
    a->cnt.unknown_id = sat_inc(a->cnt.unknown_id);
    app_send_error(a, id, PROTO_ERR_UNKNOWN_MESSAGE, id);
}

static void app_dispatch(app_state* a, const proto_frame* f) {
    if (app_is_control_frame(f->id)) flt_host_alive(&a->flt);
    switch (f->id) {
        case PROTO_ID_HELLO:
            app_send_hello(a);
            break;
        case PROTO_ID_HEARTBEAT:
            break;
        case PROTO_ID_SET_SPEEDS:
            app_on_set_speeds(a, f->payload);
            break;
        case PROTO_ID_PARAM_GET:
            if (f->payload[0] < PRM_COUNT) {
                app_send_param(a, f->payload[0]);
            } else {
                app_send_error(a, f->id, PROTO_ERR_UNKNOWN_PARAM, f->payload[0]);
            }
            break;
        case PROTO_ID_PARAM_SET:
            app_on_param_set(a, f->payload);
            break;
        case PROTO_ID_GET_STATS:
            app_send_stats(a);
            break;
        case PROTO_ID_STOP_ALL:
        case PROTO_ID_PARAM_SAVE:
        case PROTO_ID_PARAM_DEFAULTS:
            app_on_simple(a, f->id);
            break;
        case PROTO_ID_CLEAR_FAULTS:
            flt_clear(&a->flt, proto_get_u16(f->payload));
            for (uint8_t i = 0; i < APP_WHEELS; i++) grd_reset(&a->w[i].grd);
            app_send_ack(a, f->id);
            break;
        case PROTO_ID_CALIBRATE_ENC:
            app_on_calibrate(a, f->payload[0]);
            break;
        default:  // a device-to-host id sent to the device
            app_on_unknown_id(a, f->id);
            break;
    }
}

bool app_rx_decode_end(app_state* a, uint8_t byte) {
    a->rx_result = proto_rx_end(&a->rx, byte);
    return a->rx_result != PROTO_RX_NONE;
}

void app_rx_act(app_state* a) {
    const proto_frame* f = &a->rx_frame;
    const uint8_t result = a->rx_result;
    if (result == PROTO_RX_CHECK) {  // a job of its own: the dispatch follows in the next
        a->rx_result = proto_rx_check(&a->rx, &a->rx_frame);
        return;
    }
    a->rx_result = PROTO_RX_NONE;
    switch (result) {
        case PROTO_RX_FRAME:
            app_dispatch(a, f);
            break;
        case PROTO_RX_BAD_CRC:
            a->cnt.bad_crc = sat_inc(a->cnt.bad_crc);
            break;
        case PROTO_RX_SHORT:
            a->cnt.short_frame = sat_inc(a->cnt.short_frame);
            break;
        case PROTO_RX_OVERSIZE:
            a->cnt.oversize = sat_inc(a->cnt.oversize);
            break;
        case PROTO_RX_BAD_COBS:
            a->cnt.bad_cobs = sat_inc(a->cnt.bad_cobs);
            break;
        case PROTO_RX_UNKNOWN_ID:
            app_on_unknown_id(a, f->id);
            break;
        case PROTO_RX_BAD_LENGTH:
            if (!proto_to_device(f->id)) {
                app_on_unknown_id(a, f->id);  // a device-to-host id, whatever its length
                break;
            }
            a->cnt.bad_length = sat_inc(a->cnt.bad_length);
            app_send_error(a, f->id, PROTO_ERR_BAD_LENGTH, f->len);
            break;
        default:
            break;
    }
}

void app_poll_save(app_state* a) {
    if (prm_save_poll(&a->prm)) app_send_ack(a, PROTO_ID_PARAM_SAVE);
}

// ---------------------------------------------------------------- control step

void app_wheel_off(app_wheel* w, uint16_t pwm[3]) {
    pi_reset(&w->pi);
    w->drive_q15 = 0;
    w->stop_ticks = 0;
    for (uint8_t k = 0; k < 3; k++) pwm[k] = 0;
}

// Supervision of wheel i after its step (guard.h): the faults latch for the next step.
static void app_guard(app_state* a, uint8_t i) {
    app_wheel* w = &a->w[i];
    const uint8_t bit = static_cast<uint8_t>(1u << i);
    const grd_limits* g = &a->ctl.grd;
    const bool looping = (a->enable_mask & a->ctl.loop_mask & bit) != 0;
    const int16_t drive = w->drive_q15;
    const bool driven = looping && (drive >= g->drive_min_q15 || drive <= -g->drive_min_q15);
    const bool fresh = w->spd.primed && !w->spd.missed;
    const uint16_t sensor = grd_sensor(&w->grd, g, w->spd.last_angle, fresh, driven);
    if (sensor) flt_set(&a->flt, static_cast<uint16_t>(sensor | (PROTO_FAULT_ENCODER_M0 << i)));
    const uint16_t motion =
        grd_motion(&w->grd, g, looping, w->pi.saturated, drive, spd_q8(&w->spd), w->sp_q8);
    if (motion) flt_set(&a->flt, motion);
}

static void app_cal_tick(app_state* a, bool failsafe) {
    const uint8_t i = a->cal_wheel;
    uint16_t offset16 = 0;
    uint8_t outcome;
    if (flt_wheel_disabled(&a->flt, i)) {
        outcome = PROTO_CAL_ENCODER;
    } else if (failsafe) {
        outcome = PROTO_CAL_INTERRUPTED;
    } else {
        outcome = cal_tick(&a->cal, a->w[i].spd.last_angle, &offset16);
    }
    if (outcome == CAL_RUNNING) {
        a->w[i].ol_phase = static_cast<uint32_t>(a->cal.out) << 16;
    } else {
        app_cal_end(a, outcome, offset16);
    }
}

// Open loop's time limit (APP_OPEN_LOOP_MS): counted while a wheel runs open loop, from 0 again
// once all have stopped.
static void app_open_loop_tick(app_state* a) {
    if (a->ctl.closed || !a->run_mask) {
        a->open_ms = 0;
    } else if (++a->open_ms >= APP_OPEN_LOOP_MS) {
        a->open_ms = APP_OPEN_LOOP_MS;
        flt_set(&a->flt, PROTO_FAULT_OPEN_LOOP_LIMIT);
    }
}

bool app_derive_ctl(app_state* a) {
    if (a->ctl_stale == APP_CTL_STALE) {
        app_load_drive(a);
        a->ctl_stale = APP_CTL_HALF;
        return true;
    }
    if (a->ctl_stale == APP_CTL_HALF) app_load_guard(a);
    return false;
}

void app_setpoints_tick(app_state* a) {
    app_open_loop_tick(a);
    const bool failsafe = flt_heartbeat_tick(&a->flt, a->ctl.heartbeat_ms) ||
                          (a->flt.faults & PROTO_FAULT_OPEN_LOOP_LIMIT);
    if (a->cal_wheel != APP_NO_WHEEL) app_cal_tick(a, failsafe);
    const int32_t step = (failsafe || a->stopping) ? a->ctl.decel : a->ctl.accel;
    for (uint8_t i = 0; i < APP_WHEELS; i++) {
        app_wheel* w = &a->w[i];
        // Never resume by itself after a clear.
        if (failsafe || flt_wheel_disabled(&a->flt, i)) w->target_mrad_s = 0;
        if (w->sp_mrad_s == w->target_mrad_s) continue;
        w->sp_mrad_s = ramp_step(w->sp_mrad_s, w->target_mrad_s, step);
        w->sp_q8 = spd_mrad_s_to_q8(w->sp_mrad_s);
        if (w->target_mrad_s != 0) w->stop_ticks = 0;  // a new setpoint ends a stop
    }
    app_update_run_mask(a);
}

bool app_brake_on(app_wheel* w, bool was_enabled) {
    if (!was_enabled || w->stop_ticks >= APP_STOP_TICKS) return false;
    // This tick's slot of the ring holds the angle of APP_STOP_WINDOW braking ticks ago.
    uint16_t* slot = &w->brake_angles[w->stop_ticks & (APP_STOP_WINDOW - 1)];
    const uint16_t then = w->stop_ticks >= APP_STOP_WINDOW ? *slot : APP_NO_ANGLE;
    const bool fresh = w->spd.primed && !w->spd.missed;  // last_angle sampled in this tick
    *slot = fresh ? w->spd.last_angle : APP_NO_ANGLE;
    w->stop_ticks++;
    if (then == APP_NO_ANGLE || !fresh) return true;
    // The window's angle change in q8, signed in the direction the wheel was turning.
    int32_t moved = static_cast<int32_t>(spd_wrap_delta(then, *slot)) * SPD_Q8_PER_COUNT;
    if (spd_q8(&w->spd) < 0) moved = -moved;
    return moved >= static_cast<int32_t>(APP_STOP_WINDOW) * APP_STOP_Q8;
}

void app_wheel_open(const app_ctl* c, app_wheel* w, uint16_t pwm[3]) {
    w->ol_phase += static_cast<uint32_t>(cmt_phase_inc(w->sp_mrad_s, c->pole_pairs));
    int16_t amp = c->open_loop_drive;
    w->drive_q15 = w->sp_mrad_s >= 0 ? amp : static_cast<int16_t>(-amp);
    cmt_phases(static_cast<uint16_t>(w->ol_phase >> 16), amp, pwm);
}

namespace {
// Encoder words given up front (native tests, fuzzing): no transfers to overlap.
struct app_words_io {
    const uint16_t* words;
    uint16_t first() { return words[0]; }
    void next(uint8_t) {}
    uint16_t word(uint8_t i) { return words[i]; }
};
}  // namespace

void app_control_step(app_state* a, const uint16_t enc_words[APP_WHEELS]) {
    app_words_io io = {enc_words};
    app_control_step_io(a, io);
    while (app_derive_ctl(a)) {
    }
    app_setpoints_tick(a);
    for (uint8_t i = 0; i < APP_WHEELS; i++) app_supervise(a, i);
    while (app_reply_work(a)) {
    }
}

void app_supervise(app_state* a, uint8_t i) {
    if (a->ctl.closed) app_guard(a, i);
}

int32_t app_speed_mrad_s(const app_state* a, uint8_t i) {
    if (!a->ctl.closed) return a->w[i].sp_mrad_s;
    return spd_q8_to_mrad_s(spd_q8(&a->w[i].spd));
}

uint8_t app_diag_wheel(app_state* a) {
    if (!a->ctl.closed) return APP_WHEELS;
    const uint8_t i = a->diag_next;
    a->diag_next = static_cast<uint8_t>((i + 1) & (APP_WHEELS - 1));
    return i;
}

void app_diag_result(app_state* a, uint8_t wheel, uint16_t word) {
    const uint16_t bits = grd_diag(&a->w[wheel].grd, word);
    if (bits) flt_set(&a->flt, static_cast<uint16_t>(bits | (PROTO_FAULT_ENCODER_M0 << wheel)));
}

uint8_t app_status(const app_state* a) {
    uint8_t s = 0;
    if (a->enable_mask) s |= PROTO_STATUS_OUTPUTS_ENABLED;
    if (a->prm.v[PRM_MODE] != 0) s |= PROTO_STATUS_OPEN_LOOP;
    if (a->flt.faults & PROTO_FAULT_HEARTBEAT_LOST) s |= PROTO_STATUS_FAILSAFE;
    if (a->prm.saving) s |= PROTO_STATUS_SAVING;
    for (uint8_t i = 0; i < APP_WHEELS; i++) {
        if ((a->enable_mask & (1u << i)) && a->w[i].pi.saturated) {
            s = static_cast<uint8_t>(s | (PROTO_STATUS_SATURATED_M0 << i));
        }
    }
    return s;
}

void app_telemetry_begin(app_state* a, uint32_t t_us) {
    uint8_t div = static_cast<uint8_t>(a->prm.v[PRM_TELEMETRY_DIV]);
    if (div == 0) return;
    if (++a->telem_count < div) return;
    a->telem_count = 0;
    app_telem* tm = &a->tm;
    if (tm->stage !=
        APP_TELEM_IDLE) {  // the last frame is still in the making: due again next tick
        a->telem_count = static_cast<uint8_t>(div - 1);
        return;
    }
    uint8_t* p = &tm->raw[1];
    tm->raw[0] = PROTO_ID_TELEMETRY;
    proto_put_u32(&p[0], t_us);
    proto_put_u16(&p[4], a->seq++);
    tm->convert = a->ctl.closed;
    for (uint8_t i = 0; i < APP_WHEELS; i++) {
        const int32_t v = tm->convert ? spd_q8(&a->w[i].spd) : a->w[i].sp_mrad_s;
        proto_put_i32(&p[6 + 4 * i], v);
        proto_put_u16(&p[22 + 2 * i], static_cast<uint16_t>(a->w[i].drive_q15));
    }
    p[30] = app_status(a);
    proto_put_u16(&p[31], a->flt.faults);
    tm->stage = APP_TELEM_SPEEDS_01;
}

// Wheel i's speed in the frame from q8 to mrad/s, in place.
static void app_telem_convert(app_telem* tm, uint8_t i) {
    uint8_t* v = &tm->raw[1 + 6 + 4 * i];
    if (tm->convert) proto_put_i32(v, spd_q8_to_mrad_s(proto_get_i32(v)));
}

bool app_telemetry_work(app_state* a) {
    app_telem* tm = &a->tm;
    const uint8_t body = 1 + PROTO_LEN_TELEMETRY;
    switch (tm->stage) {
        case APP_TELEM_IDLE:
            return false;
        case APP_TELEM_SPEEDS_01:
            app_telem_convert(tm, 0);
            app_telem_convert(tm, 1);
            break;
        case APP_TELEM_SPEEDS_23:
            app_telem_convert(tm, 2);
            app_telem_convert(tm, 3);
            break;
        case APP_TELEM_CRC:
            proto_seal(tm->raw, body);
            break;
        case APP_TELEM_COBS:
            (void)proto_wire(tm->raw, APP_TELEM_RAW, tm->wire);
            break;
        default:  // APP_TELEM_QUEUE
            if (!a->tx(tm->wire, sizeof tm->wire)) a->cnt.tx_dropped = sat_inc(a->cnt.tx_dropped);
            tm->stage = APP_TELEM_IDLE;
            return true;
    }
    tm->stage++;
    return true;
}

void app_telemetry(app_state* a, uint32_t t_us) {
    app_telemetry_begin(a, t_us);
    while (app_telemetry_work(a)) {
    }
}

void app_note_overrun(app_state* a, uint8_t missed_ticks) {
    for (uint8_t i = 0; i < missed_ticks; i++) a->cnt.tick_overruns = sat_inc(a->cnt.tick_overruns);
    // The next encoder sample spans missed_ticks + 1 ticks: the estimator divides by that.
    for (uint8_t i = 0; i < APP_WHEELS; i++) spd_missed_ticks(&a->w[i].spd, missed_ticks);
    flt_set(&a->flt, PROTO_FAULT_TICK_OVERRUN);
}

void app_note_rx_overflow(app_state* a, uint8_t stops_seen) {
    app_note_stops_seen(a, stops_seen);
    a->stops_dispatched = a->stops_seen;  // the frames behind the count may be lost: not awaited
    a->cnt.rx_overflow = sat_inc(a->cnt.rx_overflow);
    flt_set(&a->flt, PROTO_FAULT_RX_OVERFLOW);
}

void app_note_step_time(app_state* a, uint16_t us) {
    if (us > a->cnt.step_max_us) a->cnt.step_max_us = us;
}
