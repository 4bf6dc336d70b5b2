#include "cal.h"

#include "enc.h"
#include "proto.h"
#include "speed.h"

// One electrical turn in counts, and a quarter of it.
static int16_t cal_expected(const cal_state* c) {
    return static_cast<int16_t>(ENC_COUNTS / c->pole_pairs);
}

static int16_t cal_tolerance(const cal_state* c) {
    return static_cast<int16_t>(cal_expected(c) / 4);
}

void cal_begin(cal_state* c, uint8_t pole_pairs) {
    *c = cal_state();  // CAL_ALIGN, field 0, nothing measured
    c->pole_pairs = pole_pairs;
}

// The turn forwards, on raw angles (undamped: the rotor may still swing by a fraction of the
// turn): moved, and forwards.
static uint8_t cal_check_forward(const cal_state* c, uint16_t angle) {
    const int16_t moved = spd_wrap_delta(c->a0, angle);
    if (moved > -cal_tolerance(c) && moved < cal_tolerance(c)) return PROTO_CAL_NOT_MOVED;
    return moved < 0 ? static_cast<uint8_t>(PROTO_CAL_REVERSED) : static_cast<uint8_t>(CAL_RUNNING);
}

// The turn back, between the means of two damped holds: one electrical turn.
static uint8_t cal_check_back(const cal_state* c, uint16_t a2) {
    const int16_t miss = static_cast<int16_t>(spd_wrap_delta(c->a1, a2) + cal_expected(c));
    const bool off = miss <= -cal_tolerance(c) || miss >= cal_tolerance(c);
    return off ? static_cast<uint8_t>(PROTO_CAL_POLE_PAIRS) : static_cast<uint8_t>(CAL_DONE);
}

// One tick of a hold; true at its end, with the mean angle of its last CAL_MEAN_TICKS in *mean.
static bool cal_hold(cal_state* c, uint16_t angle, uint16_t* mean) {
    const uint16_t start = CAL_HOLD_TICKS - CAL_MEAN_TICKS;
    if (c->ticks == start + 1) {
        c->ref = angle;
        c->sum = 0;
    }
    if (c->ticks > start) c->sum += spd_wrap_delta(c->ref, angle);
    if (c->ticks < CAL_HOLD_TICKS) return false;
    *mean = static_cast<uint16_t>((c->ref + (c->sum >> CAL_MEAN_SHIFT)) & ENC_MASK);
    return true;
}

// The field put out this tick: the program's angle, moved against the rotor's motion over the
// last tick (its speed in counts per tick, clamped) so that the field damps the swing.
static void cal_damp(cal_state* c, uint16_t angle) {
    int16_t d = spd_wrap_delta(c->prev_angle, angle);
    c->prev_angle = angle;
    if (d > CAL_DAMP_MAX_COUNTS) d = CAL_DAMP_MAX_COUNTS;
    if (d < -CAL_DAMP_MAX_COUNTS) d = -CAL_DAMP_MAX_COUNTS;
    c->out =
        static_cast<uint16_t>(c->field - (c->phase > CAL_FORWARD ? d * CAL_DAMP_PER_COUNT : 0));
}

uint8_t cal_tick(cal_state* c, uint16_t angle, uint16_t* offset16) {
    if (c->phase == CAL_ALIGN && c->ticks == 0) {
        if (c->pole_pairs < 3) return PROTO_CAL_POLE_PAIRS;
        c->prev_angle = angle;
    }
    cal_damp(c, angle);
    c->ticks++;
    switch (c->phase) {
        case CAL_ALIGN:
            if (c->ticks < CAL_HOLD_TICKS) return CAL_RUNNING;
            c->a0 = angle;
            break;
        case CAL_FORWARD: {
            c->field = static_cast<uint16_t>(c->field + CAL_FIELD_STEP);
            if (c->ticks < CAL_SWEEP_TICKS) return CAL_RUNNING;
            const uint8_t r = cal_check_forward(c, angle);
            if (r != CAL_RUNNING) return r;
            break;
        }
        case CAL_HOLD:
            if (!cal_hold(c, angle, &c->a1)) return CAL_RUNNING;
            break;
        case CAL_BACK:
            c->field = static_cast<uint16_t>(c->field - CAL_FIELD_STEP);
            if (c->ticks < CAL_SWEEP_TICKS) return CAL_RUNNING;
            break;
        default: {  // CAL_SETTLE
            uint16_t a2 = 0;
            if (!cal_hold(c, angle, &a2)) return CAL_RUNNING;
            const uint8_t r = cal_check_back(c, a2);
            if (r != CAL_DONE) return r;
            *offset16 = static_cast<uint16_t>(static_cast<uint16_t>(a2 * 4u) * c->pole_pairs);
            return CAL_DONE;
        }
    }
    c->phase++;
    c->ticks = 0;
    return CAL_RUNNING;
}
