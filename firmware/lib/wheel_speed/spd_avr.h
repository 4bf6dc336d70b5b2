// spd_avr.h - the common case of spd_update for the AVR in inline assembly: primed, no missed
// tick, filter gain k != 0 (spd_update takes the C path otherwise). The same steps as
// spd_update_c in spd.h: delta wrapped at 14 bits, acc += (delta * 256 - (acc >> 8)) * k with the
// difference's bytes 0..2 as a signed 24-bit operand, the product added into acc byte by byte
// (exact modulo 2^32, as the int32 sum). 59 cycles in line, no call: the step pays no call, no
// argument moves and keeps s a constant address in Z. `make -C firmware port-check` compares it
// with spd_update_c on the simulated ATmega2560. Included by spd.h on AVR only.
#ifndef SPD_AVR_H
#define SPD_AVR_H

#include <stddef.h>

static_assert(offsetof(spd_state, acc) == 0 && offsetof(spd_state, last_angle) == 4,
              "spd_state layout used by spd_update_fast_avr");

PORT_INLINE void spd_update_fast_avr(spd_state* s, uint16_t angle14, uint8_t k) {
    uint16_t last, delta;
    uint8_t a0, a1, a2, a3, d0, d1, d2, z;
    __asm__ __volatile__(
        "andi %B[ang], 0x3F\n\t"
        "ldd %A[last], Z+4\n\t"
        "ldd %B[last], Z+5\n\t"
        "std Z+4, %A[ang]\n\t"
        "std Z+5, %B[ang]\n\t"
        "movw %[del], %[ang]\n\t"  // delta = ((angle - last) << 2) >> 2, signed
        "sub %A[del], %A[last]\n\t"
        "sbc %B[del], %B[last]\n\t"
        "lsl %A[del]\n\t"
        "rol %B[del]\n\t"
        "lsl %A[del]\n\t"
        "rol %B[del]\n\t"
        "asr %B[del]\n\t"
        "ror %A[del]\n\t"
        "asr %B[del]\n\t"
        "ror %A[del]\n\t"
        "ld %[a0], Z\n\t"  // acc
        "ldd %[a1], Z+1\n\t"
        "ldd %[a2], Z+2\n\t"
        "ldd %[a3], Z+3\n\t"
        "clr %[z]\n\t"  // d = delta * 256 - (acc >> 8), bytes 0..2
        "mov %[d0], %[z]\n\t"
        "sub %[d0], %[a1]\n\t"
        "mov %[d1], %A[del]\n\t"
        "sbc %[d1], %[a2]\n\t"
        "mov %[d2], %B[del]\n\t"
        "sbc %[d2], %[a3]\n\t"
        "mul %[d0], %[k]\n\t"  // acc += d * k
        "add %[a0], r0\n\t"
        "adc %[a1], r1\n\t"
        "adc %[a2], %[z]\n\t"
        "adc %[a3], %[z]\n\t"
        "mul %[d1], %[k]\n\t"
        "add %[a1], r0\n\t"
        "adc %[a2], r1\n\t"
        "adc %[a3], %[z]\n\t"
        "mulsu %[d2], %[k]\n\t"
        "add %[a2], r0\n\t"
        "adc %[a3], r1\n\t"
        "st Z, %[a0]\n\t"
        "std Z+1, %[a1]\n\t"
        "std Z+2, %[a2]\n\t"
        "std Z+3, %[a3]\n\t"
        "clr __zero_reg__"
        : [ang] "+d"(angle14), [last] "=&r"(last), [del] "=&r"(delta), [a0] "=&r"(a0),
          [a1] "=&r"(a1), [a2] "=&r"(a2), [a3] "=&r"(a3), [d0] "=&r"(d0), [d1] "=&r"(d1),
          [d2] "=&a"(d2), [z] "=&r"(z)
        : "z"(s), [k] "a"(k)
        : "r0", "memory");
}

#endif  // SPD_AVR_H
