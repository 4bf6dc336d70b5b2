// cmt_avr.cpp - cmt_drive for the AVR in assembly (the same steps as cmt_drive_c in cmt.h, whose
// comments and those of cmt_elec_angle, cmt_lead_angle and cmt_phases explain them). Every 16 x 16
// multiply forms only the bytes it keeps: the electrical angle modulo 2^16 (two MULs), the lead
// bytes 1..2 of s * k (four), k2 = (amp * 1838) >> 16 and each phase (k2 * sin) >> 16 (four).
// `make -C firmware port-check` compares it with cmt_drive_c on the simulated ATmega2560.
// Arguments: r24:r25 mech14, r20..r23 speed_q8, r18:r19 drive, r16:r17 offset16, r14:r15 l,
// r12:r13 duty. Register use: r20:r21 k2, r22:r23 sine, r25 zero, r24 byte 1 of a product,
// r27 / r19 / r18 the table indices of phases 0 / 1 / 2, results v0 r26:r27, v1 r16:r17 (not
// saved: cmt_drive declares them clobbered), v2 r30:r31.
#include "cmt.h"

#if defined(__AVR__)
#include <stddef.h>

static_assert(offsetof(cmt_lead, k) == 0 && offsetof(cmt_lead, s_max) == 2 &&
                  offsetof(cmt_lead, pole_pairs) == 4,
              "cmt_lead layout used by cmt_drive_avr");
static_assert(CMT_PWM_MID == 400 && CMT_ANGLE_90 == 0x4000u && CMT_ANGLE_120 == 0x5555u,
              "constants used by cmt_drive_avr");

// Z = &cmt_sine_q15[idx]; then the entry in r22:r23.
#define CMT_SIN(idx)                     \
    "mov r30, " idx                      \
    "\n\t"                               \
    "ldi r31, 0\n\t"                     \
    "lsl r30\n\t"                        \
    "rol r31\n\t"                        \
    "subi r30, lo8(-(cmt_sine_q15))\n\t" \
    "sbci r31, hi8(-(cmt_sine_q15))\n\t" \
    "lpm r22, Z+\n\t"                    \
    "lpm r23, Z\n\t"

// (k2 * sin) >> 16 into hi:lo (k2 = r21:r20 >= 0, sin = r23:r22 signed, r25 = 0).
#define CMT_MULHI(lo, hi) \
    "mulsu r23, r21\n\t"  \
    "movw " lo            \
    ", r0\n\t"            \
    "mul r22, r20\n\t"    \
    "mov r24, r1\n\t"     \
    "mulsu r23, r20\n\t"  \
    "sbc " hi             \
    ", r25\n\t"           \
    "add r24, r0\n\t"     \
    "adc " lo             \
    ", r1\n\t"            \
    "adc " hi             \
    ", r25\n\t"           \
    "mul r21, r22\n\t"    \
    "add r24, r0\n\t"     \
    "adc " lo             \
    ", r1\n\t"            \
    "adc " hi ", r25\n\t"

// Signed hi = max(hi, v), lo = min(lo, v) for hi r18:r19, lo r20:r21.
#define CMT_MINMAX(vl, vh, n) \
    "cp r18, " vl             \
    "\n\t"                    \
    "cpc r19, " vh            \
    "\n\t"                    \
    "brge " n                 \
    "f\n\t"                   \
    "movw r18, " vl "\n" n    \
    ":\n\t"                   \
    "cp " vl                  \
    ", r20\n\t"               \
    "cpc " vh                 \
    ", r21\n\t"               \
    "brge 1" n                \
    "f\n\t"                   \
    "movw r20, " vl           \
    "\n"                      \
    "1" n ":\n\t"

extern "C" __attribute__((naked, used)) void cmt_drive_avr() {
    __asm__ __volatile__(
        "movw r30, r14\n\t"  // Z = l
        // ---- electrical angle: ((mech & 0x3FFF) << 2) * pole_pairs - offset, mod 2^16: r26:r27
        "andi r25, 0x3F\n\t"
        "lsl r24\n\t"
        "rol r25\n\t"
        "lsl r24\n\t"
        "rol r25\n\t"
        "ldd r23, Z+4\n\t"  // pole_pairs (byte 3 of speed_q8 is its sign: not needed)
        "mul r24, r23\n\t"
        "movw r26, r0\n\t"
        "mul r25, r23\n\t"
        "add r27, r0\n\t"
        "sub r26, r16\n\t"
        "sbc r27, r17\n\t"
        // ---- s = speed_q8 >> 6 (bytes 0..2 shifted up by two): r21:r20
        "lsl r20\n\t"
        "rol r21\n\t"
        "rol r22\n\t"
        "lsl r20\n\t"
        "rol r21\n\t"
        "rol r22\n\t"
        "mov r20, r21\n\t"
        "mov r21, r22\n\t"
        // ---- clamp to +-s_max
        "ldd r22, Z+2\n\t"
        "ldd r23, Z+3\n\t"
        "cp r22, r20\n\t"
        "cpc r23, r21\n\t"
        "brge 1f\n\t"
        "movw r20, r22\n\t"  // s = s_max
        "rjmp 2f\n"
        "1:\n\t"
        "com r23\n\t"  // -s_max
        "neg r22\n\t"
        "sbci r23, 0xFF\n\t"
        "cp r20, r22\n\t"
        "cpc r21, r23\n\t"
        "brge 2f\n\t"
        "movw r20, r22\n"  // s = -s_max
        "2:\n\t"
        // ---- angle += bytes 1..2 of s * k (k >= 0)
        "ldd r22, Z+0\n\t"
        "ldd r23, Z+1\n\t"
        "mul r20, r22\n\t"  // sl * kl: byte 1
        "mov r24, r1\n\t"
        "muls r21, r23\n\t"  // sh * kh: byte 2
        "mov r25, r0\n\t"
        "mulsu r21, r22\n\t"  // sh * kl
        "add r24, r0\n\t"
        "adc r25, r1\n\t"
        "mulsu r23, r20\n\t"  // kh * sl
        "add r24, r0\n\t"
        "adc r25, r1\n\t"
        "add r26, r24\n\t"
        "adc r27, r25\n\t"
        // ---- +-90 degrees by the sign of drive, amp = |drive| (0 for -32768): r18:r19
        "sbrc r19, 7\n\t"
        "rjmp 3f\n\t"
        "subi r27, 0xC0\n\t"  // + 0x4000
        "rjmp 4f\n"
        "3:\n\t"
        "subi r27, 0x40\n\t"  // - 0x4000
        "com r19\n\t"
        "neg r18\n\t"
        "sbci r19, 0xFF\n\t"
        "sbrs r19, 7\n\t"
        "rjmp 4f\n\t"
        "clr r18\n\t"
        "clr r19\n"
        "4:\n\t"
        // ---- k2 = (amp * 1838) >> 16, 1838 = 0x072E: r21:r20
        "clr r25\n\t"
        "ldi r22, 0x2E\n\t"
        "ldi r23, 0x07\n\t"
        "mul r18, r22\n\t"
        "mov r24, r1\n\t"
        "mul r19, r23\n\t"
        "movw r20, r0\n\t"
        "mul r18, r23\n\t"
        "add r24, r0\n\t"
        "adc r20, r1\n\t"
        "adc r21, r25\n\t"
        "mul r19, r22\n\t"
        "add r24, r0\n\t"
        "adc r20, r1\n\t"
        "adc r21, r25\n\t"
        // ---- c = angle + 90 degrees; table indices hi(c), hi(c - 0x5555), hi(c + 0x5555)
        "subi r27, 0xC0\n\t"
        "movw r18, r26\n\t"
        "subi r18, 0x55\n\t"
        "sbci r19, 0x55\n\t"  // r19 = index 1
        "subi r26, 0xAB\n\t"  // c + 0x5555 = c - 0xAAAB
        "mov r18, r27\n\t"
        "sbci r18, 0xAA\n\t"  // r18 = index 2
        // ---- the three phase voltages
        CMT_SIN("r27") CMT_MULHI("r26", "r27")  // v0
        CMT_SIN("r19") CMT_MULHI("r16", "r17")  // v1
        CMT_SIN("r18") CMT_MULHI("r30", "r31")  // v2
        // ---- hi = max, lo = min (r18:r19, r20:r21)
        "movw r18, r26\n\t"
        "movw r20, r26\n\t" CMT_MINMAX("r16", "r17", "5") CMT_MINMAX("r30", "r31", "6")
        // ---- mid = 400 - (hi + lo) / 2 (rounded towards zero): r18:r19
        "movw r24, r18\n\t"
        "add r24, r20\n\t"
        "adc r25, r21\n\t"
        "sbrc r25, 7\n\t"
        "adiw r24, 1\n\t"
        "asr r25\n\t"
        "ror r24\n\t"
        "ldi r18, lo8(400)\n\t"
        "ldi r19, hi8(400)\n\t"
        "sub r18, r24\n\t"
        "sbc r19, r25\n\t"
        // ---- duty[k] = mid + v_k
        "movw r20, r26\n\t"
        "add r20, r18\n\t"
        "adc r21, r19\n\t"
        "add r16, r18\n\t"
        "adc r17, r19\n\t"
        "movw r22, r30\n\t"
        "add r22, r18\n\t"
        "adc r23, r19\n\t"
        "movw r26, r12\n\t"
        "st X+, r20\n\t"
        "st X+, r21\n\t"
        "st X+, r16\n\t"
        "st X+, r17\n\t"
        "st X+, r22\n\t"
        "st X, r23\n\t"
        "clr r1\n\t"
        "ret\n\t" ::);
}
#endif
