#include "cmt.h"

int16_t cmt_sin(uint16_t angle16) {
    return PORT_READ_I16(&cmt_sine_q15[angle16 >> 8]);
}

uint16_t cmt_elec_angle(uint16_t mech14, uint8_t pole_pairs, uint16_t offset16) {
    // Work modulo 2^16 throughout: (4*mech mod 2^16) * pp mod 2^16 == 4*mech*pp mod 2^16.
    uint16_t m4 = static_cast<uint16_t>((mech14 & 0x3FFFu) << 2);
    // 16-bit multiply on AVR (cheap); on the host the int product (< 2^24) is truncated the same.
    uint16_t e = static_cast<uint16_t>(m4 * static_cast<uint16_t>(pole_pairs));
    return static_cast<uint16_t>(e - offset16);
}

void cmt_phases(uint16_t angle16, int16_t amp_q15, uint16_t duty[3]) {
    if (amp_q15 < 0) amp_q15 = 0;
    // Shifts by 16 (a register move on AVR) instead of 15 (a 15-step loop at -Os): k2 = 2 * k.
    int16_t k2 = static_cast<int16_t>((static_cast<int32_t>(amp_q15) * 1838) >> 16);  // 0..918
    // Phase voltages cos(a), cos(a - 120), cos(a + 120): the space vector (Clarke transform)
    // then points at angle a. cos(x) = sin(x + 90 degrees).
    uint16_t c = static_cast<uint16_t>(angle16 + CMT_ANGLE_90);
    int16_t v[3];
    v[0] = static_cast<int16_t>((static_cast<int32_t>(k2) * cmt_sin(c)) >> 16);
    v[1] = static_cast<int16_t>(
        (static_cast<int32_t>(k2) * cmt_sin(static_cast<uint16_t>(c - CMT_ANGLE_120))) >> 16);
    v[2] = static_cast<int16_t>(
        (static_cast<int32_t>(k2) * cmt_sin(static_cast<uint16_t>(c + CMT_ANGLE_120))) >> 16);
    int16_t hi = v[0], lo = v[0];
    for (uint8_t i = 1; i < 3; i++) {
        if (v[i] > hi) hi = v[i];
        if (v[i] < lo) lo = v[i];
    }
    int16_t off = static_cast<int16_t>((hi + lo) / 2);
    for (uint8_t i = 0; i < 3; i++) {
        duty[i] = static_cast<uint16_t>(CMT_PWM_MID + v[i] - off);
    }
}

int32_t cmt_phase_inc(int32_t speed_mrad_s, uint8_t pole_pairs) {
    int32_t es = speed_mrad_s * static_cast<int32_t>(pole_pairs);
    int32_t mag = es < 0 ? -es : es;
    // Beyond half an electrical turn per tick the rotation aliases; clamp so the product fits.
    if (mag > CMT_MAX_ELEC_MRAD_S) mag = CMT_MAX_ELEC_MRAD_S;
    int32_t inc = mag * 683 + ((mag * 145) >> 8);
    return es < 0 ? -inc : inc;
}
