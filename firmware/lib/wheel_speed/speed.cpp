#include "speed.h"

void spd_init(spd_state* s) {
    s->acc = 0;
    s->last_angle = 0;
    s->primed = 0;
    s->missed = 0;
}

uint8_t spd_gain(uint8_t shift) {
    if (shift > SPD_MAX_SHIFT) shift = SPD_MAX_SHIFT;
    return shift == 0 ? 0 : static_cast<uint8_t>(1u << (8 - shift));
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

int32_t spd_gap_q8(spd_state* s, int16_t delta) {
    // The delta spans missed + 1 ticks (rare: only after bad encoder words).
    int32_t x = spd_div_ticks(static_cast<int32_t>(delta) * SPD_Q8_PER_COUNT,
                              static_cast<uint8_t>(s->missed + 1));
    s->missed = 0;
    return x;
}

void spd_missed_ticks(spd_state* s, uint8_t n) {
    // spd_div_ticks divides by 1..3 ticks: a longer gap re-primes (the estimate is held).
    if (static_cast<uint16_t>(s->missed) + n <= 2u) {
        s->missed = static_cast<uint8_t>(s->missed + n);
    } else {
        s->primed = 0;
        s->missed = 0;
    }
}

void spd_skip(spd_state* s) {
    spd_missed_ticks(s, 1);
}

int32_t spd_q8_to_mrad_s(int32_t q8) {
    // |q8| = h * 2^16 + l: |q8| * 98175 / 2^16 = h * 98175 + l + (l * 32639) / 2^16, exact in
    // 32 bits for |q8| <= 2^22 (h <= 64).
    uint32_t n = q8 < 0 ? 0u - static_cast<uint32_t>(q8) : static_cast<uint32_t>(q8);
    uint16_t h = static_cast<uint16_t>(n >> 16);
    uint16_t l = static_cast<uint16_t>(n);
    uint32_t m =
        port_mul_u16(h, 32639u) + (static_cast<uint32_t>(h) << 16) + l + port_mulhi_u16(l, 32639u);
    return q8 < 0 ? -static_cast<int32_t>(m) : static_cast<int32_t>(m);
}

int32_t spd_mrad_s_to_q8(int32_t mrad_s) {
    // 256 / 383.4952 = 0.667544 ~ 43748 / 65536; |mrad/s| = h * 2^16 + l as above.
    uint32_t n = mrad_s < 0 ? 0u - static_cast<uint32_t>(mrad_s) : static_cast<uint32_t>(mrad_s);
    uint16_t h = static_cast<uint16_t>(n >> 16);
    uint16_t l = static_cast<uint16_t>(n);
    uint32_t m = port_mul_u16(h, 43748u) + port_mulhi_u16(l, 43748u);
    return mrad_s < 0 ? -static_cast<int32_t>(m) : static_cast<int32_t>(m);
}
