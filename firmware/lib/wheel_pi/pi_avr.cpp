// pi_avr.cpp - pi_step_mag for the AVR in assembly (the same steps as pi_step_mag_c in pi.h, whose
// comments explain them). avr-gcc 5.4 keeps the 24- and 32-bit intermediates of the C version in
// memory and spent about 455 cycles per wheel on it inside the step; this took about 260 per call
// with the saves of r12..r17, r28, r29, about 225 since it only saves r28:r29 (the caller,
// pi_step_mag in pi.h, declares r12..r17 clobbered: mean of `make -C firmware cycles`, PROFILE).
// `make -C firmware port-check` compares it with pi_step_mag_c on the simulated ATmega2560 over
// the gain, limit and error extremes and random sequences (the native tests run the C version).
// Register use: X = s, Z = g until the gains are read, T = neg, r16 = 0, r17 = (mag != 0),
// r12:r13 = lo, r14:r15 = hi (mirrored), r18:r19 = out_max, r24:r25 = P; returns y in r24:r25.
#include "pi.h"

#if defined(__AVR__)
#include <stddef.h>

static_assert(offsetof(pi_state, integ) == 0 && offsetof(pi_state, out) == 3 &&
                  offsetof(pi_state, saturated) == 5 && sizeof(port_i24) == 3,
              "pi_state layout used by pi_step_mag_avr");
static_assert(offsetof(pi_gains, kp_q8) == 0 && offsetof(pi_gains, ki_q8) == 2 &&
                  offsetof(pi_gains, out_max) == 4 && offsetof(pi_gains, slew) == 6,
              "pi_gains layout used by pi_step_mag_avr");

extern "C" __attribute__((naked, used)) void pi_step_mag_avr() {
    __asm__ __volatile__(
        "push r28\n\t"
        "push r29\n\t"
        "movw r28, r18\n\t"  // mag
        "movw r26, r24\n\t"  // X = s
        "movw r30, r22\n\t"  // Z = g
        "bst r20, 0\n\t"     // T = neg
        "clr r16\n\t"
        // ---- lo = max(out - slew, -out_max), hi = min(out + slew, out_max), lo <= hi
        "adiw r26, 3\n\t"
        "ld r24, X+\n\t"  // out
        "ld r25, X\n\t"
        "sbiw r26, 4\n\t"
        "ldd r22, Z+6\n\t"  // slew
        "ldd r23, Z+7\n\t"
        "ldd r18, Z+4\n\t"  // out_max
        "ldd r19, Z+5\n\t"
        "movw r20, r22\n\t"
        "sub r20, r18\n\t"  // slew - out_max
        "sbc r21, r19\n\t"
        "cp r24, r20\n\t"
        "cpc r25, r21\n\t"
        "brlt 1f\n\t"
        "movw r12, r24\n\t"  // lo = out - slew
        "sub r12, r22\n\t"
        "sbc r13, r23\n\t"
        "rjmp 2f\n"
        "1:\n\t"
        "clr r12\n\t"  // lo = -out_max
        "clr r13\n\t"
        "sub r12, r18\n\t"
        "sbc r13, r19\n"
        "2:\n\t"
        "movw r20, r18\n\t"
        "sub r20, r22\n\t"  // out_max - slew
        "sbc r21, r23\n\t"
        "cp r20, r24\n\t"
        "cpc r21, r25\n\t"
        "brlt 3f\n\t"
        "movw r14, r24\n\t"  // hi = out + slew
        "add r14, r22\n\t"
        "adc r15, r23\n\t"
        "rjmp 4f\n"
        "3:\n\t"
        "movw r14, r18\n"  // hi = out_max
        "4:\n\t"
        "cp r14, r12\n\t"
        "cpc r15, r13\n\t"
        "brge 5f\n\t"
        "movw r12, r14\n"  // lo = hi
        "5:\n\t"
        "brtc 6f\n\t"  // mirror: lo' = -hi, hi' = -lo
        "movw r20, r12\n\t"
        "clr r12\n\t"
        "clr r13\n\t"
        "sub r12, r14\n\t"
        "sbc r13, r15\n\t"
        "clr r14\n\t"
        "clr r15\n\t"
        "sub r14, r20\n\t"
        "sbc r15, r21\n"
        "6:\n\t"
        // ---- P = kp * mag (+ 255 if neg) >> 8, saturated to 0xFFFF: r24:r25
        "ldd r24, Z+0\n\t"
        "ldd r25, Z+1\n\t"
        "mul r24, r28\n\t"
        "movw r20, r0\n\t"
        "mul r25, r29\n\t"
        "movw r22, r0\n\t"
        "mul r24, r29\n\t"
        "add r21, r0\n\t"
        "adc r22, r1\n\t"
        "adc r23, r16\n\t"
        "mul r25, r28\n\t"
        "add r21, r0\n\t"
        "adc r22, r1\n\t"
        "adc r23, r16\n\t"
        "brtc 7f\n\t"
        "subi r20, 0x01\n\t"  // + 255
        "sbci r21, 0xFF\n\t"
        "sbci r22, 0xFF\n\t"
        "sbci r23, 0xFF\n"
        "7:\n\t"
        "mov r24, r21\n\t"
        "mov r25, r22\n\t"
        "tst r23\n\t"
        "breq 8f\n\t"
        "ldi r24, 0xFF\n\t"
        "ldi r25, 0xFF\n"
        "8:\n\t"
        // ---- di = ki * mag: r20..r23; clamped to 2 * out_max * 256
        "ldd r0, Z+2\n\t"
        "ldd r31, Z+3\n\t"
        "mov r30, r0\n\t"
        "mul r30, r28\n\t"
        "movw r20, r0\n\t"
        "mul r31, r29\n\t"
        "movw r22, r0\n\t"
        "mul r30, r29\n\t"
        "add r21, r0\n\t"
        "adc r22, r1\n\t"
        "adc r23, r16\n\t"
        "mul r31, r28\n\t"
        "add r21, r0\n\t"
        "adc r22, r1\n\t"
        "adc r23, r16\n\t"
        "mov r17, r28\n\t"  // mag != 0
        "or r17, r29\n\t"
        "movw r30, r18\n\t"
        "lsl r30\n\t"  // out_max << 1: bytes 1..2 of the clamp
        "rol r31\n\t"
        "cp r16, r20\n\t"
        "cpc r30, r21\n\t"
        "cpc r31, r22\n\t"
        "cpc r16, r23\n\t"
        "brsh 9f\n\t"
        "clr r20\n\t"
        "mov r21, r30\n\t"
        "mov r22, r31\n\t"
        "clr r23\n"
        "9:\n\t"
        // ---- I' = +-s->integ (r28..r30), sum = I' + di (32 bits), clamped to +-ilim
        "ld r28, X+\n\t"
        "ld r29, X+\n\t"
        "ld r30, X\n\t"
        "sbiw r26, 2\n\t"
        "brtc 10f\n\t"
        "com r30\n\t"
        "com r29\n\t"
        "neg r28\n\t"
        "sbci r29, 0xFF\n\t"
        "sbci r30, 0xFF\n"
        "10:\n\t"
        "ldi r31, 0\n\t"
        "sbrc r30, 7\n\t"
        "ldi r31, 0xFF\n\t"
        "add r20, r28\n\t"
        "adc r21, r29\n\t"
        "adc r22, r30\n\t"
        "adc r23, r31\n\t"
        "cp r16, r20\n\t"  // ilim - sum
        "cpc r18, r21\n\t"
        "cpc r19, r22\n\t"
        "cpc r16, r23\n\t"
        "brge 11f\n\t"
        "clr r20\n\t"  // sum = ilim
        "mov r21, r18\n\t"
        "mov r22, r19\n\t"
        "rjmp 13f\n"
        "11:\n\t"
        "add r21, r18\n\t"  // sum + ilim < 0 ?
        "adc r22, r19\n\t"
        "adc r23, r16\n\t"
        "brpl 12f\n\t"
        "clr r20\n\t"  // sum = -ilim
        "clr r21\n\t"
        "clr r22\n\t"
        "sub r21, r18\n\t"
        "sbc r22, r19\n\t"
        "rjmp 13f\n"
        "12:\n\t"
        "sub r21, r18\n\t"  // undo
        "sbc r22, r19\n"
        "13:\n\t"
        // ---- u = P + (I + round) / 256 (24 bits): r29:r30:r31; I in r20..r22
        "mov r28, r20\n\t"
        "mov r29, r21\n\t"
        "mov r30, r22\n\t"
        "brtc 14f\n\t"
        "subi r28, 0x01\n\t"  // + 255: round up in the mirrored case
        "sbci r29, 0xFF\n\t"
        "sbci r30, 0xFF\n"
        "14:\n\t"
        "ldi r31, 0\n\t"
        "sbrc r30, 7\n\t"
        "ldi r31, 0xFF\n\t"
        "add r29, r24\n\t"
        "adc r30, r25\n\t"
        "adc r31, r16\n\t"
        // ---- back-calculation while the upper limit holds (once: r17 cleared after it)
        "tst r17\n\t"
        "breq 20f\n\t"
        "ldi r23, 0\n\t"
        "sbrc r15, 7\n\t"
        "ldi r23, 0xFF\n\t"
        "cp r14, r29\n\t"  // hi - u
        "cpc r15, r30\n\t"
        "cpc r23, r31\n\t"
        "brge 20f\n\t"
        "clr r17\n\t"
        "mov r29, r14\n\t"  // c = hi - P (24 bits)
        "mov r30, r15\n\t"
        "mov r31, r23\n\t"
        "sub r29, r24\n\t"
        "sbc r30, r25\n\t"
        "sbc r31, r16\n\t"
        "add r29, r18\n\t"  // c + out_max < 0 ?
        "adc r30, r19\n\t"
        "adc r31, r16\n\t"
        "brpl 15f\n\t"
        "clr r29\n\t"  // c = -out_max
        "clr r30\n\t"
        "sub r29, r18\n\t"
        "sbc r30, r19\n\t"
        "rjmp 16f\n"
        "15:\n\t"
        "sub r29, r18\n\t"  // undo; c <= hi fits 16 bits
        "sbc r30, r19\n"
        "16:\n\t"
        "ld r23, X+\n\t"  // I' again: r23, r28, r31
        "ld r28, X+\n\t"
        "ld r31, X\n\t"
        "sbiw r26, 2\n\t"
        "brtc 17f\n\t"
        "com r31\n\t"
        "com r28\n\t"
        "neg r23\n\t"
        "sbci r28, 0xFF\n\t"
        "sbci r31, 0xFF\n"
        "17:\n\t"
        "cp r23, r16\n\t"  // I' - cap, cap = c * 256
        "cpc r28, r29\n\t"
        "cpc r31, r30\n\t"
        "brge 18f\n\t"
        "clr r20\n\t"  // I = cap
        "mov r21, r29\n\t"
        "mov r22, r30\n\t"
        "rjmp 19f\n"
        "18:\n\t"
        "mov r20, r23\n\t"  // I = I'
        "mov r21, r28\n\t"
        "mov r22, r31\n"
        "19:\n\t"
        "cp r16, r20\n\t"  // ilim - I
        "cpc r18, r21\n\t"
        "cpc r19, r22\n\t"
        "brlt 25f\n\t"
        "rjmp 13b\n"
        "25:\n\t"
        "clr r20\n\t"  // I = ilim
        "mov r21, r18\n\t"
        "mov r22, r19\n\t"
        "rjmp 13b\n"
        // ---- y = clamp(u, lo, hi), saturated flag in r28
        "20:\n\t"
        "ldi r28, 1\n\t"
        "ldi r23, 0\n\t"
        "sbrc r15, 7\n\t"
        "ldi r23, 0xFF\n\t"
        "cp r14, r29\n\t"  // hi - u
        "cpc r15, r30\n\t"
        "cpc r23, r31\n\t"
        "brge 21f\n\t"
        "movw r24, r14\n\t"
        "rjmp 23f\n"
        "21:\n\t"
        "ldi r23, 0\n\t"
        "sbrc r13, 7\n\t"
        "ldi r23, 0xFF\n\t"
        "cp r29, r12\n\t"  // u - lo
        "cpc r30, r13\n\t"
        "cpc r31, r23\n\t"
        "brge 22f\n\t"
        "movw r24, r12\n\t"
        "rjmp 23f\n"
        "22:\n\t"
        "mov r24, r29\n\t"
        "mov r25, r30\n\t"
        "clr r28\n"
        "23:\n\t"
        "brtc 24f\n\t"  // mirror back: I = -I, y = -y
        "com r22\n\t"
        "com r21\n\t"
        "neg r20\n\t"
        "sbci r21, 0xFF\n\t"
        "sbci r22, 0xFF\n\t"
        "com r25\n\t"
        "neg r24\n\t"
        "sbci r25, 0xFF\n"
        "24:\n\t"
        "st X+, r20\n\t"
        "st X+, r21\n\t"
        "st X+, r22\n\t"
        "st X+, r24\n\t"
        "st X+, r25\n\t"
        "st X, r28\n\t"
        "clr r1\n\t"
        "pop r29\n\t"
        "pop r28\n\t"
        "ret\n\t" ::);
}
#endif
