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

// sin of a 16-bit angle, Q15.
int16_t cmt_sin(uint16_t angle16);

// Electrical angle from a 14-bit mechanical angle: mech * 4 * pole_pairs - offset, modulo 65536.
uint16_t cmt_elec_angle(uint16_t mech14, uint8_t pole_pairs, uint16_t offset16);

// Three PWM compare values (0..CMT_PWM_TOP) for a voltage vector at angle16 with amplitude
// amp_q15 (0..32767, larger values are clamped).
void cmt_phases(uint16_t angle16, int16_t amp_q15, uint16_t duty[3]);

// Per-tick increment of a 32-bit phase accumulator (2^32 = one electrical turn) for a mechanical
// speed in mrad/s: es * 2^32 / (2*pi*1e6) with es = speed * pole_pairs (electrical mrad/s),
// computed as es*683 + es*145/256 (relative error 1e-5). |es| is clamped to CMT_MAX_ELEC_MRAD_S
// (0.49 electrical turns per tick; 3000 rpm at 7 pole pairs is 2.2e6). |speed| <= 2^31/40.
#define CMT_MAX_ELEC_MRAD_S 3100000L
int32_t cmt_phase_inc(int32_t speed_mrad_s, uint8_t pole_pairs);

#endif  // CMT_H
