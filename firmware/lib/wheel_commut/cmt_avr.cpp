// cmt_avr.cpp - cmt_drive for the AVR in assembly (the same steps as cmt_drive_c in cmt.h, whose
// comments and those of cmt_elec_angle, cmt_lead_angle and cmt_svm_duties explain them). Every
// 16 x 16 multiply forms only the bytes it keeps: the electrical angle modulo 2^16 (two MULs,
// mech * 4 * pole_pairs with 4 * pole_pairs from the cmt_lead), the lead bytes 1..2 of s * k
// (four), each phase (drive * cmt_svm) >> 16 (four). The sign of the drive needs no branch (the
// table is odd: cmt.h), the clamp of the lead's speed compares high bytes first.
// Cycles (positive lead speed, no clamp; one more for a negative one): 138 from the first
// instruction to the RET included, 168 per call in the control step with the caller's set-up
// (four LDS, three MOVW, two LDI: 13), the CALL (5) and the stores of the duties (six STS: 12).
// `make -C firmware port-check` compares it with cmt_drive_c on the simulated ATmega2560.
// Arguments: r24:r25 mech14, r20..r23 speed_q8, r18:r19 drive (kept), r16:r17 offset16, r30:r31
// l. Results: duties of phases a, b, c in r22:r23, r20:r21, r24:r25. Register use: r26:r27 the
// angle, r21:r22 the lead's speed, r2 zero, r3 byte 1 of a product, r16:r17 a table entry,
// r30:r31 Z into the table.
#include "cmt.h"

#if defined(__AVR__)
#include <stddef.h>

static_assert(offsetof(cmt_lead, k) == 0 && offsetof(cmt_lead, s_max) == 2 &&
                  offsetof(cmt_lead, pp4) == 5,
              "cmt_lead layout used by cmt_drive_avr");
static_assert(CMT_PWM_MID == 400 && CMT_ANGLE_120 == 0x5555u && CMT_TABLE_SIZE == 256,
              "constants used by cmt_drive_avr");

// Duty of a phase into lo:hi: 400 + ((drive * entry) >> 16), drive r19:r18, entry r17:r16 (both
// signed), r2 = 0.
#define CMT_PHASE(lo, hi) \
    "muls r19, r17\n\t"   \
    "movw " lo            \
    ", r0\n\t"            \
    "mul r18, r16\n\t"    \
    "mov r3, r1\n\t"      \
    "mulsu r19, r16\n\t"  \
    "sbc " hi             \
    ", r2\n\t"            \
    "add r3, r0\n\t"      \
    "adc " lo             \
    ", r1\n\t"            \
    "adc " hi             \
    ", r2\n\t"            \
    "mulsu r17, r18\n\t"  \
    "sbc " hi             \
    ", r2\n\t"            \
    "add r3, r0\n\t"      \
    "adc " lo             \
    ", r1\n\t"            \
    "adc " hi             \
    ", r2\n\t"            \
    "subi " lo            \
    ", lo8(-400)\n\t"     \
    "sbci " hi ", hi8(-400)\n\t"

extern "C" __attribute__((naked, used)) void cmt_drive_avr() {
    __asm__ __volatile__(
        // ---- electrical angle: mech * (4 * pole_pairs) - offset, mod 2^16: r26:r27
        "ldd r23, Z+5\n\t"  // 4 * pole_pairs (byte 3 of speed_q8 is its sign: not needed)
        "mul r24, r23\n\t"
        "movw r26, r0\n\t"
        "mul r25, r23\n\t"
        "add r27, r0\n\t"
        "sub r26, r16\n\t"
        "sbc r27, r17\n\t"
        // ---- s = speed_q8 >> 6 (bytes 0..2 shifted up by two): r21:r22
        "lsl r20\n\t"
        "rol r21\n\t"
        "rol r22\n\t"
        "lsl r20\n\t"
        "rol r21\n\t"
        "rol r22\n\t"
        // ---- clamp to +-s_max; first on the high bytes alone (s_max >= 808)
        "ldd r23, Z+3\n\t"  // high byte of s_max
        "sbrc r22, 7\n\t"
        "rjmp 2f\n\t"
        "cp r22, r23\n\t"  // hi(s) < hi(s_max): s < s_max
        "brlt 4f\n\t"
        "ldd r16, Z+2\n\t"
        "cp r16, r21\n\t"
        "cpc r23, r22\n\t"
        "brge 4f\n\t"
        "mov r21, r16\n\t"  // s = s_max
        "mov r22, r23\n\t"
        "rjmp 4f\n"
        "2:\n\t"
        "add r23, r22\n\t"  // hi(s) >= -hi(s_max): s >= 256 * hi(s) >= -s_max
        "brge 4f\n\t"
        "ldd r16, Z+2\n\t"
        "ldd r17, Z+3\n\t"
        "add r16, r21\n\t"
        "adc r17, r22\n\t"
        "brge 4f\n\t"  // s + s_max >= 0
        "ldd r21, Z+2\n\t"
        "ldd r22, Z+3\n\t"
        "com r22\n\t"  // s = -s_max
        "neg r21\n\t"
        "sbci r22, 0xFF\n"
        "4:\n\t"
        // ---- rotor angle: += bytes 1..2 of s * k (k >= 0)
        "ldd r16, Z+0\n\t"
        "ldd r17, Z+1\n\t"
        "clr r2\n\t"
        "mul r21, r16\n\t"  // sl * kl: byte 1
        "add r26, r1\n\t"
        "adc r27, r2\n\t"
        "mul r22, r17\n\t"  // sh * kh: byte 2
        "add r27, r0\n\t"
        "mulsu r22, r16\n\t"  // sh * kl
        "add r26, r0\n\t"
        "adc r27, r1\n\t"
        "mul r17, r21\n\t"  // kh * sl
        "add r26, r0\n\t"
        "adc r27, r1\n\t"
        // ---- phase a: entry hi(rotor)
        "mov r30, r27\n\t"
        "ldi r31, hi8(cmt_svm_tab)\n\t"
        "lpm r16, Z\n\t"
        "inc r31\n\t"
        "lpm r17, Z\n\t" CMT_PHASE("r22", "r23")
        // ---- phase b: entry hi(rotor - 0x5555)
        "cpi r26, 0x55\n\t"
        "mov r30, r27\n\t"
        "sbci r30, 0x55\n\t"
        "lpm r17, Z\n\t"
        "dec r31\n\t"
        "lpm r16, Z\n\t" CMT_PHASE("r20", "r21")
        // ---- phase c: entry hi(rotor + 0x5555) = hi(rotor) + 0x55 + (lo(rotor) >= 0xAB)
        "cpi r26, 0xAB\n\t"
        "mov r30, r27\n\t"
        "sbci r30, 0xAA\n\t"
        "lpm r16, Z\n\t"
        "inc r31\n\t"
        "lpm r17, Z\n\t" CMT_PHASE("r24", "r25")
        "clr r1\n\t"
        "ret\n\t" ::);
}
#endif
