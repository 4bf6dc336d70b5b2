// pi_avr.h - the call of the PI step's assembly (pi_avr.cpp) on the AVR; included by pi.h on AVR
// only. The assembly is kept because the C step (pi_step_err_c) costs about 970 more cycles per
// control step, and with it the documented link flood overflowed the receive ring
// (docs/hardware.md, "Control-step cycles").
#ifndef PI_AVR_H
#define PI_AVR_H

// Not avr-gcc ABI functions. pi_step_err_avr (pi_avr.cpp) takes s in X (r26:r27), g in Z
// (r30:r31) and e in r18..r21, returns y in r24:r25 and clobbers r0, r3..r25, X and Z without
// saving any of them (the control step's caller has the call-saved ones saved in its own prologue
// anyway; saving them would cost two cycles per register and call). Its rare cases (out_max
// shrunk below the state) jump to pi_step_mag_slow, the ABI function in pi_avr.cpp that runs
// pi_step_mag_c. Only called through pi_step_err below, which tells the compiler.
extern "C" void pi_step_err_avr_entry();
extern "C" int16_t pi_step_mag_slow(pi_state* s, const pi_gains* g, bool neg, uint16_t mag);

PORT_INLINE int16_t pi_step_err(pi_state* s, const pi_gains* g, int32_t e) {
    register pi_state* r_s __asm__("r26") = s;
    register const pi_gains* r_g __asm__("r30") = g;
    register int32_t r_e __asm__("r18") = e;
    register int16_t r_y __asm__("r24");
    __asm__ __volatile__("call pi_step_err_avr_entry"
                         : "=r"(r_y), "+r"(r_s), "+r"(r_g), "+r"(r_e)
                         :
                         : "r0", "r3", "r4", "r5", "r6", "r7", "r8", "r9", "r10", "r11", "r12",
                           "r13", "r14", "r15", "r16", "r17", "r22", "r23", "memory");
    return r_y;
}

#endif  // PI_AVR_H
