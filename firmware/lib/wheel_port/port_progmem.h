// port_progmem.h - the one portability shim of the portable firmware logic.
// On AVR, constant tables live in flash (PROGMEM) and are read with pgm_read_word; on the host
// they are plain const arrays. No other file in firmware/lib/ may include an AVR header.
// Also the widening multiplies of the control step (see port_mul_u16 below).
#ifndef PORT_PROGMEM_H
#define PORT_PROGMEM_H

#include <stdint.h>

// Small helpers of the control step: inlined even at -Os (a call costs more than their body).
#if defined(__GNUC__)
#define PORT_INLINE inline __attribute__((always_inline))
#else
#define PORT_INLINE inline
#endif

// Signed 24-bit integer for values proven to stay within +-2^23 (PI integrator, speed in q8):
// avr-gcc's __int24 (3-byte arithmetic instead of 4), int32_t on the host. The native tests run the
// int32 form, so overflow of 24 bits is checked on the chip by `make -C firmware port-check`.
#if defined(__AVR__)
typedef __int24 port_i24;
#else
typedef int32_t port_i24;
#endif

#if defined(__AVR__)
#include <avr/pgmspace.h>
#define PORT_PROGMEM PROGMEM
#define PORT_READ_I32(addr) (static_cast<int32_t>(pgm_read_dword(addr)))
#define PORT_READ_I16(addr) (static_cast<int16_t>(pgm_read_word(addr)))
#define PORT_READ_U8(addr) (static_cast<uint8_t>(pgm_read_byte(addr)))
#else
#define PORT_PROGMEM
#define PORT_READ_I32(addr) (*(addr))
#define PORT_READ_I16(addr) (*(addr))
#define PORT_READ_U8(addr) (*(addr))
#endif

// Widening 16 x 16 -> 32 multiplies. avr-gcc 5.4 widens such products to 16 x 32 library calls
// and spills registers around them, so on AVR they are inline MUL/MULS/MULSU sequences (Atmel
// AVR201; 17 cycles, no call); on the host, plain C (what the native tests exercise). The AVR
// sequences are checked against the C expressions in simavr by `make -C firmware port-check`.
// Every result fits: a * b <= 2^32 - 2^17 + 1 unsigned, |a * b| <= 2^30 signed.
PORT_INLINE uint32_t port_mul_u16(uint16_t a, uint16_t b) {
#if defined(__AVR__)
    uint32_t r;
    uint8_t z;
    __asm__(
        "clr %[z]\n\t"
        "mul %B[a], %B[b]\n\t"
        "movw %C[r], r0\n\t"
        "mul %A[a], %A[b]\n\t"
        "movw %A[r], r0\n\t"
        "mul %A[a], %B[b]\n\t"
        "add %B[r], r0\n\t"
        "adc %C[r], r1\n\t"
        "adc %D[r], %[z]\n\t"
        "mul %B[a], %A[b]\n\t"
        "add %B[r], r0\n\t"
        "adc %C[r], r1\n\t"
        "adc %D[r], %[z]\n\t"
        "clr __zero_reg__"
        : [r] "=&r"(r), [z] "=&r"(z)
        : [a] "r"(a), [b] "r"(b));
    return r;
#else
    return static_cast<uint32_t>(a) * static_cast<uint32_t>(b);
#endif
}

PORT_INLINE int32_t port_mul_s16(int16_t a, int16_t b) {
#if defined(__AVR__)
    int32_t r;
    uint8_t z;
    __asm__(
        "clr %[z]\n\t"
        "muls %B[a], %B[b]\n\t"
        "movw %C[r], r0\n\t"
        "mul %A[a], %A[b]\n\t"
        "movw %A[r], r0\n\t"
        "mulsu %B[a], %A[b]\n\t"
        "sbc %D[r], %[z]\n\t"
        "add %B[r], r0\n\t"
        "adc %C[r], r1\n\t"
        "adc %D[r], %[z]\n\t"
        "mulsu %B[b], %A[a]\n\t"
        "sbc %D[r], %[z]\n\t"
        "add %B[r], r0\n\t"
        "adc %C[r], r1\n\t"
        "adc %D[r], %[z]\n\t"
        "clr __zero_reg__"
        : [r] "=&r"(r), [z] "=&r"(z)
        : [a] "a"(a), [b] "a"(b));  // MULS/MULSU take r16..r23 only
    return r;
#else
    return static_cast<int32_t>(a) * static_cast<int32_t>(b);
#endif
}

// High word of the signed product, (a * b) >> 16 rounded towards minus infinity. On AVR the low
// byte of the product is never formed (14 cycles, 4 registers besides the operands).
PORT_INLINE int16_t port_mulhi_s16(int16_t a, int16_t b) {
#if defined(__AVR__)
    int16_t r;
    uint8_t t, z;
    __asm__(
        "clr %[z]\n\t"
        "muls %B[a], %B[b]\n\t"
        "movw %A[r], r0\n\t"
        "mul %A[a], %A[b]\n\t"
        "mov %[t], r1\n\t"
        "mulsu %B[a], %A[b]\n\t"
        "sbc %B[r], %[z]\n\t"
        "add %[t], r0\n\t"
        "adc %A[r], r1\n\t"
        "adc %B[r], %[z]\n\t"
        "mulsu %B[b], %A[a]\n\t"
        "sbc %B[r], %[z]\n\t"
        "add %[t], r0\n\t"
        "adc %A[r], r1\n\t"
        "adc %B[r], %[z]\n\t"
        "clr __zero_reg__"
        : [r] "=&r"(r), [t] "=&r"(t), [z] "=&r"(z)
        : [a] "a"(a), [b] "a"(b));
    return r;
#else
    return static_cast<int16_t>(port_mul_s16(a, b) >> 16);
#endif
}

// High word of the unsigned product, (a * b) >> 16 (the speed-unit conversion of the PI error).
PORT_INLINE uint16_t port_mulhi_u16(uint16_t a, uint16_t b) {
#if defined(__AVR__)
    uint16_t r;
    uint8_t t, z;
    __asm__(
        "clr %[z]\n\t"
        "mul %B[a], %B[b]\n\t"
        "movw %A[r], r0\n\t"
        "mul %A[a], %A[b]\n\t"
        "mov %[t], r1\n\t"
        "mul %A[a], %B[b]\n\t"
        "add %[t], r0\n\t"
        "adc %A[r], r1\n\t"
        "adc %B[r], %[z]\n\t"
        "mul %B[a], %A[b]\n\t"
        "add %[t], r0\n\t"
        "adc %A[r], r1\n\t"
        "adc %B[r], %[z]\n\t"
        "clr __zero_reg__"
        : [r] "=&r"(r), [t] "=&r"(t), [z] "=&r"(z)
        : [a] "r"(a), [b] "r"(b));
    return r;
#else
    return static_cast<uint16_t>(port_mul_u16(a, b) >> 16);
#endif
}

// a * b for a signed 24-bit a (|a| < 2^23, held in an int32) and an 8-bit b: the speed
// estimator's filter gain 2^(8 - shift). |a * b| < 2^31. On AVR three MULs (12 cycles) instead of
// a variable shift loop or a 32 x 32 __mulsi3; byte 3 of a is ignored there, so a must be in range
// (the native tests check the estimator's bound, port-check compares the two on the chip).
PORT_INLINE int32_t port_mul_s24_u8(int32_t a, uint8_t b) {
#if defined(__AVR__)
    int32_t r;
    uint8_t z;
    __asm__(
        "clr %[z]\n\t"
        "mul %A[a], %[b]\n\t"
        "movw %A[r], r0\n\t"
        "mulsu %C[a], %[b]\n\t"
        "movw %C[r], r0\n\t"
        "mul %B[a], %[b]\n\t"
        "add %B[r], r0\n\t"
        "adc %C[r], r1\n\t"
        "adc %D[r], %[z]\n\t"
        "clr __zero_reg__"
        : [r] "=&r"(r), [z] "=&r"(z)
        : [a] "a"(a), [b] "a"(b));  // MULSU takes r16..r23 only
    return r;
#else
    return a * static_cast<int32_t>(b);
#endif
}

#endif  // PORT_PROGMEM_H
