#include "cmt.h"

void cmt_phases(uint16_t angle16, int16_t amp_q15, uint16_t duty[3]) {
    if (amp_q15 < 0) amp_q15 = 0;
    // Only 16 x 16 -> 32 multiplies whose high word is taken (no shift loops at -Os): k2 = 2 * k.
    int16_t k2 = port_mulhi_s16(amp_q15, 1838);  // 0..918
    // Phase voltages cos(a), cos(a - 120), cos(a + 120): the space vector (Clarke transform)
    // then points at angle a. cos(x) = sin(x + 90 degrees).
    uint16_t c = static_cast<uint16_t>(angle16 + CMT_ANGLE_90);
    int16_t v0 = port_mulhi_s16(k2, cmt_sin(c));
    int16_t v1 = port_mulhi_s16(k2, cmt_sin(static_cast<uint16_t>(c - CMT_ANGLE_120)));
    int16_t v2 = port_mulhi_s16(k2, cmt_sin(static_cast<uint16_t>(c + CMT_ANGLE_120)));
    int16_t hi = v0, lo = v0;
    if (v1 > hi) hi = v1;
    if (v1 < lo) lo = v1;
    if (v2 > hi) hi = v2;
    if (v2 < lo) lo = v2;
    // Centre on the mid supply minus the zero sequence (hi + lo) / 2 (|hi + lo| < 2^11).
    int16_t mid = static_cast<int16_t>(CMT_PWM_MID - (hi + lo) / 2);
    duty[0] = static_cast<uint16_t>(mid + v0);
    duty[1] = static_cast<uint16_t>(mid + v1);
    duty[2] = static_cast<uint16_t>(mid + v2);
}

int32_t cmt_phase_inc(int32_t speed_mrad_s, uint8_t pole_pairs) {
    int32_t es = speed_mrad_s * static_cast<int32_t>(pole_pairs);
    int32_t mag = es < 0 ? -es : es;
    // Beyond half an electrical turn per tick the rotation aliases; clamp so the product fits.
    if (mag > CMT_MAX_ELEC_MRAD_S) mag = CMT_MAX_ELEC_MRAD_S;
    int32_t inc = mag * 683 + ((mag * 145) >> 8);
    return es < 0 ? -inc : inc;
}

void cmt_lead_init(cmt_lead* l, uint8_t pole_pairs, uint16_t lead_q8) {
    if (pole_pairs == 0) pole_pairs = 1;
    // 2^24 / (2*pi*1e6) = 2.6701773; pole_pairs * lead_q8 <= 40 * 512 keeps k below 2^16 and
    // pl * 67018 below 2^31 (once per parameter change: the division is not in the step).
    uint32_t pl = static_cast<uint32_t>(pole_pairs) * lead_q8;
    uint32_t k = 2u * pl + (pl * 67018u + 50000u) / 100000u;
    l->k = static_cast<uint16_t>(k > 0xFFFFu ? 0xFFFFu : k);
    uint32_t smax = (static_cast<uint32_t>(CMT_MAX_ELEC_MRAD_S) / pole_pairs) >> 8;
    l->s8_max = static_cast<uint16_t>(smax);
}
