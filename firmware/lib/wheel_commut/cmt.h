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
// amp_q15 (0..32767, negative values give 0). Inline: the control step runs it for every wheel.
PORT_INLINE void cmt_phases(uint16_t angle16, int16_t amp_q15, uint16_t duty[3]) {
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

// Per-tick increment of a 32-bit phase accumulator (2^32 = one electrical turn) for a mechanical
// speed in mrad/s: es * 2^32 / (2*pi*1e6) with es = speed * pole_pairs (electrical mrad/s),
// computed as es*683 + es*145/256 (relative error 1e-5). |es| is clamped to CMT_MAX_ELEC_MRAD_S
// (0.49 electrical turns per tick; 3000 rpm at 7 pole pairs is 2.2e6). |speed| <= 2^31/40.
#define CMT_MAX_ELEC_MRAD_S 3100000L
int32_t cmt_phase_inc(int32_t speed_mrad_s, uint8_t pole_pairs);

// Commutation lead: electrical angle advance (65536 = one turn) = speed * pole_pairs * lead time,
// lead time = lead_q8 / 256 ticks, for a speed in q8 (encoder counts per tick * 256, see spd.h).
// One mechanical count is 4 * pole_pairs angle units, so
//   lead = speed_q8 * pole_pairs * lead_q8 / 2^14 = (speed_q8 >> 6) * k >> 8,  k = pole_pairs *
// lead_q8 <= 40 * 512 = 20480, with speed_q8 >> 6 (a quarter count per tick, |.| <= 2^15)
// clamped to the aliasing limit CMT_MAX_ELEC_MRAD_S / pole_pairs as cmt_phase_inc. One signed
// 16 x 16 -> 32 multiply per tick (cmt_lead_angle), k and the clamp set up once per parameter
// change (cmt_lead_init). Error against the exact value: below k/256 + 1 angle units (speed
// truncated to a quarter count, product floored); 4.5 units (0.025 degrees electrical) at 7 pole
// pairs and the default lead of 128/256 tick.
struct cmt_lead {
    int16_t k;
    int16_t s_max;       // clamp of |speed_q8 >> 6|
    uint8_t pole_pairs;  // 1..40, as cmt_elec_angle takes it (cmt_drive)
};
void cmt_lead_init(cmt_lead* l, uint8_t pole_pairs, uint16_t lead_q8);
PORT_INLINE uint16_t cmt_lead_angle(const cmt_lead* l, int32_t speed_q8) {
    // |speed_q8| <= 2^21, so speed_q8 >> 6 fits int16; formed from bytes 1..2 shifted up by two
    // and the top two bits of byte 0 (no 6-step shift loop of a 32-bit value at -Os).
    int16_t s =
        static_cast<int16_t>(static_cast<uint16_t>(static_cast<uint16_t>(speed_q8 >> 8) << 2) |
                             static_cast<uint8_t>(static_cast<uint8_t>(speed_q8) >> 6));
    if (s > l->s_max) {
        s = l->s_max;
    } else if (s < -l->s_max) {
        s = static_cast<int16_t>(-l->s_max);
    }
    return static_cast<uint16_t>(static_cast<uint32_t>(port_mul_s16(s, l->k)) >> 8);
}

// The commutation of one closed-loop wheel in the control step: electrical angle of the 14-bit
// mechanical angle (cmt_elec_angle with l->pole_pairs and offset16), advanced by the lead
// (cmt_lead_angle), then 90 degrees electrical ahead of the rotor for drive >= 0 (amplitude drive)
// or behind it for drive < 0 (amplitude -drive), and the three duties of cmt_phases.
// cmt_drive_c is the reference in C (what the native tests run); on AVR cmt_drive is
// cmt_drive_avr (cmt_avr.cpp, assembly with the 16 x 16 multiplies reduced to the bytes used,
// compared with cmt_drive_c on the chip by `make -C firmware port-check`).
PORT_INLINE void cmt_drive_c(uint16_t mech14, int32_t speed_q8, int16_t drive, uint16_t offset16,
                             const cmt_lead* l, uint16_t duty[3]) {
    uint16_t angle16 = static_cast<uint16_t>(cmt_elec_angle(mech14, l->pole_pairs, offset16) +
                                             cmt_lead_angle(l, speed_q8));
    int16_t amp;
    if (drive >= 0) {
        angle16 = static_cast<uint16_t>(angle16 + CMT_ANGLE_90);
        amp = drive;
    } else {
        angle16 = static_cast<uint16_t>(angle16 - CMT_ANGLE_90);
        // In 16 bits (int on AVR): -32768 stays negative, and cmt_phases takes it as 0.
        amp = static_cast<int16_t>(0u - static_cast<uint16_t>(drive));
    }
    cmt_phases(angle16, amp, duty);
}

#if defined(__AVR__)
// Not an avr-gcc ABI function: the arguments in the ABI's registers (r24:r25 mech14, r20..r23
// speed_q8, r18:r19 drive, r16:r17 offset16, r14:r15 l, r12:r13 duty), but r16:r17 clobbered
// (not saved: 8 cycles per call). Only called through cmt_drive below, which tells the compiler.
extern "C" void cmt_drive_avr();
#endif

PORT_INLINE void cmt_drive(uint16_t mech14, int32_t speed_q8, int16_t drive, uint16_t offset16,
                           const cmt_lead* l, uint16_t duty[3]) {
#if defined(__AVR__)
    register uint16_t r_m __asm__("r24") = mech14;
    register int32_t r_sp __asm__("r20") = speed_q8;
    register int16_t r_d __asm__("r18") = drive;
    register uint16_t r_o __asm__("r16") = offset16;
    register uint16_t r_l __asm__("r14") = static_cast<uint16_t>(reinterpret_cast<uintptr_t>(l));
    register uint16_t r_du __asm__("r12") =
        static_cast<uint16_t>(reinterpret_cast<uintptr_t>(duty));
    __asm__ __volatile__("call cmt_drive_avr"
                         : "+r"(r_m), "+r"(r_sp), "+r"(r_d), "+r"(r_o)
                         : "r"(r_l), "r"(r_du)
                         : "r0", "r26", "r27", "r30", "r31", "memory");
#else
    cmt_drive_c(mech14, speed_q8, drive, offset16, l, duty);
#endif
}

#endif  // CMT_H
