#include "spd.h"

void spd_init(spd_state* s) {
    s->acc = 0;
    s->speed_mrad_s = 0;
    s->last_angle = 0;
    s->primed = 0;
    s->missed = 0;
}

int16_t spd_wrap_delta(uint16_t a, uint16_t b) {
    // Shift the 14-bit difference into the top of a 16-bit word, then back with sign extension.
    uint16_t d = static_cast<uint16_t>(static_cast<uint16_t>(b - a) << 2);
    return static_cast<int16_t>(static_cast<int16_t>(d) / 4);
}

int32_t spd_counts_to_mrad_s(int16_t counts_per_tick) {
    const int32_t k_q8 = 98175;  // 383.496 mrad/s per count per 1 ms tick, times 256
    if (counts_per_tick >= 0) return (static_cast<int32_t>(counts_per_tick) * k_q8) >> 8;
    return -((static_cast<int32_t>(-counts_per_tick) * k_q8) >> 8);
}

int32_t spd_update(spd_state* s, uint16_t angle14, uint8_t shift) {
    if (shift > SPD_MAX_SHIFT) shift = SPD_MAX_SHIFT;
    angle14 = static_cast<uint16_t>(angle14 & 0x3FFFu);
    if (!s->primed) {
        s->primed = 1;
        s->missed = 0;
        s->last_angle = angle14;
        return s->speed_mrad_s;
    }
    int16_t delta = spd_wrap_delta(s->last_angle, angle14);
    s->last_angle = angle14;
    int32_t raw = spd_counts_to_mrad_s(delta);
    if (s->missed) {
        // The delta spans missed + 1 ticks (rare: only after bad encoder words).
        raw /= static_cast<int32_t>(s->missed) + 1;
        s->missed = 0;
    }
    s->acc += raw - (s->acc >> shift);
    s->speed_mrad_s = s->acc >> shift;
    return s->speed_mrad_s;
}

void spd_skip(spd_state* s) {
    // A gap of more than a quarter turn per tick count is ambiguous anyway: re-prime after 3 ticks.
    if (s->missed < 2) {
        s->missed++;
    } else {
        s->primed = 0;
        s->missed = 0;
    }
}
