// spd_avr.cpp - the common case of spd_update for the AVR in assembly: primed, no missed tick,
// filter gain k != 0 (spd_update takes the C path otherwise). The same steps as spd_update_c in
// spd.h: delta wrapped at 14 bits, x = delta * 256, acc += (x - (acc >> 8)) * k with the
// difference's bytes 0..2 as the signed 24-bit operand of port_mul_s24_u8. About 40 cycles
// instead of about 125 for the C inside the step. `make -C firmware port-check` compares it with
// spd_update_c on the simulated ATmega2560.
// Arguments: r24:r25 s, r22:r23 angle14, r20 k. Z = s, acc in r18/r19/r24/r25.
#include "spd.h"

#if defined(__AVR__)
#include <stddef.h>

static_assert(offsetof(spd_state, acc) == 0 && offsetof(spd_state, last_angle) == 4,
              "spd_state layout used by spd_update_fast_avr");

extern "C" __attribute__((naked, used)) void spd_update_fast_avr(spd_state*, uint16_t, uint8_t) {
    __asm__ __volatile__(
        "movw r30, r24\n\t"
        "andi r23, 0x3F\n\t"
        "ldd r18, Z+4\n\t"  // last angle
        "ldd r19, Z+5\n\t"
        "std Z+4, r22\n\t"
        "std Z+5, r23\n\t"
        "movw r26, r22\n\t"  // delta = ((angle - last) << 2) >> 2 (signed): r26:r27
        "sub r26, r18\n\t"
        "sbc r27, r19\n\t"
        "lsl r26\n\t"
        "rol r27\n\t"
        "lsl r26\n\t"
        "rol r27\n\t"
        "asr r27\n\t"
        "ror r26\n\t"
        "asr r27\n\t"
        "ror r26\n\t"
        "ld r18, Z\n\t"  // acc
        "ldd r19, Z+1\n\t"
        "ldd r24, Z+2\n\t"
        "ldd r25, Z+3\n\t"
        // d = delta * 256 - (acc >> 8), bytes 0..2: r22, r23, r21
        "clr r22\n\t"
        "sub r22, r19\n\t"
        "mov r23, r26\n\t"
        "sbc r23, r24\n\t"
        "mov r21, r27\n\t"
        "sbc r21, r25\n\t"
        // p = d * k: r26, r27, r0, r1
        "mul r22, r20\n\t"
        "movw r26, r0\n\t"
        "mul r23, r20\n\t"
        "movw r22, r0\n\t"
        "mulsu r21, r20\n\t"
        "clr r21\n\t"
        "add r27, r22\n\t"
        "adc r0, r23\n\t"
        "adc r1, r21\n\t"
        // acc += p
        "add r18, r26\n\t"
        "adc r19, r27\n\t"
        "adc r24, r0\n\t"
        "adc r25, r1\n\t"
        "st Z, r18\n\t"
        "std Z+1, r19\n\t"
        "std Z+2, r24\n\t"
        "std Z+3, r25\n\t"
        "clr r1\n\t"
        "ret\n\t" ::);
}
#endif
