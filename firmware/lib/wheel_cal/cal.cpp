#include "cal.h"

#include "enc.h"
#include "proto.h"
#include "spd.h"

void cal_begin(cal_state* c, uint8_t pole_pairs) {
    c->field = 0;
    c->ticks = 0;
    c->a0 = 0;
    c->a1 = 0;
    c->phase = CAL_ALIGN;
    c->pole_pairs = pole_pairs;
}

// The checks of the two turns: moved forwards by one electrical turn, and back again.
static uint8_t cal_check(const cal_state* c, uint16_t a2) {
    if (c->pole_pairs < 3) return PROTO_CAL_POLE_PAIRS;
    const int16_t expected = static_cast<int16_t>(ENC_COUNTS / c->pole_pairs);
    const int16_t tolerance = static_cast<int16_t>(expected / 4);
    const int16_t moved = spd_wrap_delta(c->a0, c->a1);
    const int16_t back = spd_wrap_delta(c->a1, a2);
    if (moved > -tolerance && moved < tolerance) return PROTO_CAL_NOT_MOVED;
    if (moved < 0) return PROTO_CAL_REVERSED;
    const int16_t miss = static_cast<int16_t>(moved - expected);
    const int16_t gap = static_cast<int16_t>(moved + back);
    if (miss <= -tolerance || miss >= tolerance || gap <= -tolerance || gap >= tolerance) {
        return PROTO_CAL_POLE_PAIRS;
    }
    return CAL_DONE;
}

uint8_t cal_tick(cal_state* c, uint16_t angle, uint16_t* offset16) {
    c->ticks++;
    switch (c->phase) {
        case CAL_ALIGN:
            if (c->ticks < CAL_ALIGN_TICKS) return CAL_RUNNING;
            c->a0 = angle;
            break;
        case CAL_FORWARD:
            c->field = static_cast<uint16_t>(c->field + CAL_FIELD_STEP);
            if (c->ticks < CAL_SWEEP_TICKS) return CAL_RUNNING;
            c->a1 = angle;
            break;
        case CAL_BACK:
            c->field = static_cast<uint16_t>(c->field - CAL_FIELD_STEP);
            if (c->ticks < CAL_SWEEP_TICKS) return CAL_RUNNING;
            break;
        default: {  // CAL_SETTLE
            if (c->ticks < CAL_SETTLE_TICKS) return CAL_RUNNING;
            const uint8_t r = cal_check(c, angle);
            if (r != CAL_DONE) return r;
            const uint16_t mean = static_cast<uint16_t>(
                (c->a0 + spd_wrap_delta(c->a0, angle) / 2) & ENC_MASK);
            *offset16 = static_cast<uint16_t>(static_cast<uint16_t>(mean * 4u) * c->pole_pairs);
            return CAL_DONE;
        }
    }
    c->phase++;
    c->ticks = 0;
    return CAL_RUNNING;
}
