// cmt.h - sine commutation with min-max (SVPWM-equivalent) zero-sequence injection.
// The voltage space vector of the three duties points at the given electrical angle
// (phase a = cos(angle), b = cos(angle - 120 deg), c = cos(angle + 120 deg)).
//
// Angles are 16-bit: 65536 = one electrical revolution. The table has 256 entries (index = top 8
// bits of the angle, 1.4 degrees electrical). Drive amplitude is Q15 (32767 = full voltage). The
// three phase voltages are centred by -(max+min)/2, which lets the line-to-line voltage reach the
// full supply (2/sqrt(3) more than plain sine): duty = 400 + k*sin(...) - offset, k = a*460/32768,
// peak |duty - 400| <= 0.866 * 459 = 398 < 400 for TOP = 799.
#ifndef CMT_H
#define CMT_H

#include <stdint.h>

#include "port_progmem.h"

#define CMT_TABLE_SIZE 256
#define CMT_PWM_TOP 799
#define CMT_PWM_MID 400
#define CMT_ANGLE_90 0x4000u
#define CMT_ANGLE_120 21845u

extern const int16_t cmt_sine_q15[CMT_TABLE_SIZE] PORT_PROGMEM;

// sin of a 16-bit angle, Q15 (table index = high byte of the angle).
inline int16_t cmt_sin(uint16_t angle16) {
    return PORT_READ_I16(&cmt_sine_q15[static_cast<uint8_t>(angle16 >> 8)]);
}

// Electrical angle from a 14-bit mechanical angle: mech * 4 * pole_pairs - offset, modulo 65536.
PORT_INLINE uint16_t cmt_elec_angle(uint16_t mech14, uint8_t pole_pairs, uint16_t offset16) {
    // Work modulo 2^16 throughout: (4*mech mod 2^16) * pp mod 2^16 == 4*mech*pp mod 2^16.
    uint16_t m4 = static_cast<uint16_t>((mech14 & 0x3FFFu) << 2);
    // 16-bit multiply on AVR (cheap); on the host the int product (< 2^24) is truncated the same.
    uint16_t e = static_cast<uint16_t>(m4 * static_cast<uint16_t>(pole_pairs));
    return static_cast<uint16_t>(e - offset16);
}

// Three PWM compare values (0..CMT_PWM_TOP) for a voltage vector at angle16 with amplitude
// amp_q15 (0..32767, larger values are clamped).
void cmt_phases(uint16_t angle16, int16_t amp_q15, uint16_t duty[3]);

// Per-tick increment of a 32-bit phase accumulator (2^32 = one electrical turn) for a mechanical
// speed in mrad/s: es * 2^32 / (2*pi*1e6) with es = speed * pole_pairs (electrical mrad/s),
// computed as es*683 + es*145/256 (relative error 1e-5). |es| is clamped to CMT_MAX_ELEC_MRAD_S
// (0.49 electrical turns per tick; 3000 rpm at 7 pole pairs is 2.2e6). |speed| <= 2^31/40.
#define CMT_MAX_ELEC_MRAD_S 3100000L
int32_t cmt_phase_inc(int32_t speed_mrad_s, uint8_t pole_pairs);

// Commutation lead: electrical angle advance (65536 = one turn) = speed * pole_pairs * lead time,
// lead time = lead_q8 / 256 ticks. Set up once per parameter change (cmt_lead_init), evaluated
// per tick with one 16 x 16 -> 32 multiply (cmt_lead_angle):
//   lead = (|speed| >> 8) * k >> 8, k = round(pole_pairs * lead_q8 * 2^24 / (2*pi*1e6)) <= 54685,
// |speed| >> 8 clamped to the aliasing limit CMT_MAX_ELEC_MRAD_S / pole_pairs as cmt_phase_inc.
// Error against the exact value: below k/256 + |speed|/2^17 + 2 angle units (speed truncated to
// 256 mrad/s, k rounded); 12 units (0.07 degrees electrical) up to 1500 rpm at 7 pole pairs and
// the default lead of 128/256 tick.
struct cmt_lead {
    uint16_t k;
    uint16_t s8_max;  // clamp of |speed| >> 8
};
void cmt_lead_init(cmt_lead* l, uint8_t pole_pairs, uint16_t lead_q8);
PORT_INLINE uint16_t cmt_lead_angle(const cmt_lead* l, int32_t speed_mrad_s) {
    bool neg = speed_mrad_s < 0;
    uint32_t mag =
        neg ? 0u - static_cast<uint32_t>(speed_mrad_s) : static_cast<uint32_t>(speed_mrad_s);
    uint32_t s8 = mag >> 8;
    uint16_t s = s8 > l->s8_max ? l->s8_max : static_cast<uint16_t>(s8);
    uint16_t lead = static_cast<uint16_t>(port_mul_u16(s, l->k) >> 8);  // modulo one turn
    return neg ? static_cast<uint16_t>(0u - lead) : lead;
}

#endif  // CMT_H
