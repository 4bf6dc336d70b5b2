#include "spd.h"

void spd_init(spd_state* s) {
    s->acc = 0;
    s->speed_mrad_s = 0;
    s->last_angle = 0;
    s->primed = 0;
    s->missed = 0;
    s->shift = 0;
}

int16_t spd_wrap_delta(uint16_t a, uint16_t b) {
    // Shift the 14-bit difference into the top of a 16-bit word, then back with sign extension.
    uint16_t d = static_cast<uint16_t>(static_cast<uint16_t>(b - a) << 2);
    return static_cast<int16_t>(static_cast<int16_t>(d) / 4);
}

int32_t spd_div_ticks(int32_t x, uint8_t ticks) {
    if (ticks < 2) return x;
    uint32_t n = x < 0 ? 0u - static_cast<uint32_t>(x) : static_cast<uint32_t>(x);
    uint32_t q;
    if (ticks == 2) {
        q = n >> 1;
    } else {
        // Exact n / 3 for every uint32 (Hacker's Delight, divu3): shifts and adds, no divide.
        q = (n >> 2) + (n >> 4);
        q += q >> 4;
        q += q >> 8;
        q += q >> 16;
        uint32_t r = n - q * 3u;  // 0..5
        q += (11u * r) >> 5;
    }
    return x < 0 ? -static_cast<int32_t>(q) : static_cast<int32_t>(q);
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
        raw = spd_div_ticks(raw, static_cast<uint8_t>(s->missed + 1));
        s->missed = 0;
    }
    // acc >> shift is the last output unless the shift changed: one variable shift per update.
    int32_t y = (shift == s->shift) ? s->speed_mrad_s : (s->acc >> shift);
    s->shift = shift;
    s->acc += raw - y;
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
