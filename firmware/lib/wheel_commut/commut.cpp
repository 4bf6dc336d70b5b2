#include "commut.h"

#include "speed.h"

int32_t cmt_phase_inc(int32_t speed_mrad_s, uint8_t pole_pairs) {
    int32_t es = speed_mrad_s * static_cast<int32_t>(pole_pairs);
    int32_t mag = es < 0 ? -es : es;
    // Beyond half an electrical turn per tick the rotation aliases; clamp so the product fits.
    if (mag > CMT_MAX_ELEC_MRAD_S) mag = CMT_MAX_ELEC_MRAD_S;
    int32_t inc = mag * 683 + ((mag * 145) >> 8);
    return es < 0 ? -inc : inc;
}

void cmt_lead_poles(cmt_lead* l, uint8_t pole_pairs) {
    if (pole_pairs == 0) pole_pairs = 1;
    if (pole_pairs > 40) pole_pairs = 40;
    l->pole_pairs = pole_pairs;
    // Aliasing limit in q8 >> 6 (once per parameter change: the division is not in the step);
    // at most 2069380 >> 6 = 32334 for one pole pair.
    int32_t q8 = spd_mrad_s_to_q8(CMT_MAX_ELEC_MRAD_S / pole_pairs);
    l->s_max = static_cast<int16_t>(q8 >> 6);
}

void cmt_lead_time(cmt_lead* l, uint16_t lead_q8) {
    if (lead_q8 > 512) lead_q8 = 512;
    l->k = static_cast<int16_t>(static_cast<uint16_t>(l->pole_pairs) * lead_q8);  // <= 20480
}
