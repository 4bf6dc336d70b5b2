// pi_avr.cpp - pi_step_err for the AVR in assembly: the same results as pi_step_err_c (pi.h) for
// every state, gain and error, computed in the signed domain instead of mirroring a negative
// error onto a positive one. `make -C firmware port-check` compares the two on the simulated
// ATmega2560 over the gain, limit and error extremes and random sequences (the native tests run
// the C version).
//
// In the signed domain, with E = clamp(e, +-65535), lo/hi the output window of pi_step_mag_c:
//   P = clamp(floor(kp * E / 256), +-65535)
//     (E < 0: P = -pmc, pmc = min(ceil(kp * |E| / 256), 65535))
//   I = clamp(integ + sign(E) * min(ki * |E|, 2 ilim), +-ilim),  u = P + floor(I / 256)
//   E > 0 and u > hi: c = max(hi - P, -out_max), I = min(max(c * 256, integ), ilim), y = hi
//   E < 0 and u < lo: c = min(lo - P, out_max), I = max(min(c * 256, integ), -ilim), y = lo
//   otherwise y = clamp(u, lo, hi); saturated = (y != u), u recomputed from the final I.
// Shortcuts that the port-check proves exact:
// - With integ >= -ilim (E > 0) the clamp of the increment changes nothing (integ + 2 ilim >=
//   ilim), so I = min(integ + D, ilim); mirrored for E < 0 with integ <= ilim.
// - E = 0 takes the E > 0 path including the back-calculation: with P = 0 and u > hi, the
//   back-calculated I is min(integ, ilim), the integrator's own result, and y = hi, sat = 1 as
//   without it.
// - In the back-calculation y is always the limit (the new u is never inside the window), and
//   I = cap gives u = hi (lo) exactly, saturated = 0; otherwise I is the previous integrator
//   (unchanged in memory) and only the flag needs the comparison.
// - The unlimited output: for E >= 0, u >= floor(I / 256) >= -out_max, so only the slew side of
//   lo is compared; mirrored for E < 0.
// The rare cases where the limits or the integrator lie outside the window (out_max shrank below
// the last output or integrator: lo > hi possible, |integ| > ilim) jump to pi_step_mag_slow
// (below: the C reference) with (s, g, neg, mag) in the ABI's registers.
//
// One path per sign (entered by the sign bit of e; each has its copy of the multiplies so that
// every branch stays within reach). Register use: X = s (loads with X+, stores backwards with
// -X), Z = g (kept for the fallback), r18:r19 = |e| clamped (mag, kept for the fallback),
// r21 = 0, r24:r25 = kp, ki, then out, r3..r5 = integ (E < 0: I in place, integ = I + D when
// needed), r6:r7 = out_max, r8:r9 = slew, r10..r13 = ki * mag (E >= 0: then I),
// r14 = byte 0 of kp * mag, r15:r16 = bytes 1, 2 (P), r22:r23 = hi (E >= 0) or lo (E < 0),
// r0, r1, r20 scratch; y returned in r24:r25. r2 and r28:r29 are not touched.
//
// Cycle budget (ATmega2560, including the final ret; the caller adds its call, 5, and four ldi
// for X and Z): magnitude 5 (E >= 0) or 11 (E < 0, with the jump to its path); multiplies and
// loads 60 (two 16 x 16 -> 32 products 16 each, 13 loads); then to the end
//   E >= 0, output inside the window                    125
//   E >= 0, back-calculated at hi (I = cap)             128
//   E < 0, output inside the window                     134
//   E < 0, back-calculated at lo (I = cap)              144
// and a few more where a clamp acts (e or P or D saturated, I at +-ilim, lo or hi at out_max).
// Measured: 132.5 per call on average in the PC profile of `make -C firmware cycles` (four
// wheels at +-715 rpm, about a third of the steps back-calculated); pi_step_mag_avr with the
// C conversion of the error to mrad/s before it took about 235 + 45.
// The C fallback (pi_step_mag_slow) costs about 500 but only runs after out_max was lowered
// below the state; never in that bench.
#include "pi.h"

#if defined(__AVR__)
#include <stddef.h>

static_assert(offsetof(pi_state, integ) == 0 && offsetof(pi_state, out) == 3 &&
                  offsetof(pi_state, saturated) == 5 && sizeof(port_i24) == 3,
              "pi_state layout used by pi_step_err_avr");
static_assert(offsetof(pi_gains, kp_q8) == 0 && offsetof(pi_gains, ki_q8) == 2 &&
                  offsetof(pi_gains, out_max) == 4 && offsetof(pi_gains, slew) == 6,
              "pi_gains layout used by pi_step_err_avr");

// The multiplies and loads both signs share (a copy in each path, so that the branches stay
// within reach and no sign test is repeated): p = kp * mag, D = ki * mag, state and limits.
// X is left at s + 5 (saturated), from where the stores run backwards.
#define PI_COMMON(PSAT, PDONE, DSAT, DDONE) \
    "ldd r24, Z+0\n\t"                      \
    "ldd r25, Z+1\n\t"                      \
    "mul r24, r18\n\t"                      \
    "movw r14, r0\n\t"                      \
    "mul r25, r19\n\t"                      \
    "movw r16, r0\n\t"                      \
    "mul r24, r19\n\t"                      \
    "add r15, r0\n\t"                       \
    "adc r16, r1\n\t"                       \
    "adc r17, r21\n\t"                      \
    "mul r25, r18\n\t"                      \
    "add r15, r0\n\t"                       \
    "adc r16, r1\n\t"                       \
    "adc r17, r21\n\t"                      \
    "brne " PSAT "\n" PDONE                 \
    ":\n\t"                                 \
    "ldd r24, Z+2\n\t"                      \
    "ldd r25, Z+3\n\t"                      \
    "mul r24, r18\n\t"                      \
    "movw r10, r0\n\t"                      \
    "mul r25, r19\n\t"                      \
    "movw r12, r0\n\t"                      \
    "mul r24, r19\n\t"                      \
    "add r11, r0\n\t"                       \
    "adc r12, r1\n\t"                       \
    "adc r13, r21\n\t"                      \
    "mul r25, r18\n\t"                      \
    "add r11, r0\n\t"                       \
    "adc r12, r1\n\t"                       \
    "adc r13, r21\n\t"                      \
    "brne " DSAT "\n" DDONE                 \
    ":\n\t"                                 \
    "ld r3, X+\n\t"                         \
    "ld r4, X+\n\t"                         \
    "ld r5, X+\n\t"                         \
    "ld r24, X+\n\t"                        \
    "ld r25, X+\n\t"                        \
    "ldd r6, Z+4\n\t"                       \
    "ldd r7, Z+5\n\t"                       \
    "ldd r8, Z+6\n\t"                       \
    "ldd r9, Z+7\n\t"

// The rare cases of the multiplies: |P| = 65535 (byte 0 cleared: no ceiling on top) and
// D = 2^24 - 1, above any 2 ilim, which gives the same clamped integrator.
#define PI_SATS(PSAT, PDONE, DSAT, DDONE) \
    PSAT ":\n\t"                          \
         "clr r14\n\t"                    \
         "ldi r16, 0xFF\n\t"              \
         "mov r15, r16\n\t"               \
         "rjmp " PDONE "\n" DSAT          \
         ":\n\t"                          \
         "ldi r20, 0xFF\n\t"              \
         "mov r10, r20\n\t"               \
         "mov r11, r20\n\t"               \
         "mov r12, r20\n\t"               \
         "clr r13\n\t"                    \
         "rjmp " DDONE "\n"

// Return: the saturated flag SAT, y (r24:r25) and the integrator bytes I2, I1, I0 stored
// backwards from X = s + 5; PI_RETURN_Y leaves the integrator as it is in memory.
#define PI_RETURN(SAT, I2, I1, I0)                                                              \
    "st X, " SAT "\n\tst -X, r25\n\tst -X, r24\n\tst -X, " I2 "\n\tst -X, " I1 "\n\tst -X, " I0 \
    "\n\tclr r1\n\tret\n"
#define PI_RETURN_Y(SAT) "st X, " SAT "\n\tst -X, r25\n\tst -X, r24\n\tclr r1\n\tret\n"

// pi_step_mag_slow(s, g, neg, mag): the C reference for the rare cases.
#define PI_SLOW(NEG)        \
    "sbiw r26, 5\n\t"       \
    "movw r24, r26\n\t"     \
    "movw r22, r30\n\t" NEG \
    "clr r1\n\t"            \
    "jmp pi_step_mag_slow\n"

// The entry is pi_step_err_avr_entry below, after the rare blocks of the E >= 0 path (placed
// first so that its branches reach them).
extern "C" __attribute__((naked, used)) void pi_step_err_avr() {
    __asm__ __volatile__(
        // ================= E >= 0: rare blocks
        ".Lpm_sat:\n\t"  // e > 65535
        "ldi r18, 0xFF\n\t"
        "ldi r19, 0xFF\n\t"
        "clr r21\n\t"
        "rjmp .Lpm_done\n" PI_SATS(".Lpp_sat", ".Lpp_done", ".Lpd_sat", ".Lpd_done")

        // ================= entry: X = s, Z = g, r18..r21 = e, r1 = 0
        ".global pi_step_err_avr_entry\n"
        "pi_step_err_avr_entry:\n\t"
        "sbrc r21, 7\n\t"
        "rjmp .Lneg_all\n\t"
        // ================= E >= 0: mag = min(e, 65535) in r18:r19
        "cp r20, r1\n\t"
        "cpc r21, r1\n\t"
        "brne .Lpm_sat\n"
        ".Lpm_done:\n\t"  // r21 = 0 (the zero register from here on)
        PI_COMMON(".Lpp_sat", ".Lpp_done", ".Lpd_sat", ".Lpd_done")
        // integ >= -ilim (floor(integ / 256) + out_max >= 0), else C
        "movw r22, r4\n\t"
        "add r22, r6\n\t"
        "adc r23, r7\n\t"
        "brlt .Lpos_slow\n\t"
        // I = min(integ + D, ilim) (32 bits): r10..r12
        "mov r20, r5\n\t"
        "lsl r20\n\t"
        "sbc r20, r20\n\t"
        "add r10, r3\n\t"
        "adc r11, r4\n\t"
        "adc r12, r5\n\t"
        "adc r13, r20\n\t"
        "cp r21, r10\n\t"
        "cpc r6, r11\n\t"
        "cpc r7, r12\n\t"
        "cpc r21, r13\n\t"
        "brlt .Lpos_imax\n"
        ".Lpos_i:\n\t"
        // hi = min(out + slew, out_max): r22:r23
        "movw r22, r24\n\t"
        "add r22, r8\n\t"
        "adc r23, r9\n\t"
        "brvs 1f\n\t"
        "cp r6, r22\n\t"
        "cpc r7, r23\n\t"
        "brge 2f\n"
        "1:\n\t"
        "movw r22, r6\n"
        "2:\n\t"
        // u > hi?  w = hi - floor(I / 256) < 0, or P > w
        "movw r0, r22\n\t"
        "sub r0, r11\n\t"
        "sbc r1, r12\n\t"
        "brlt .Lpos_above\n\t"
        "sub r0, r15\n\t"
        "sbc r1, r16\n\t"
        "brcs .Lpos_above\n\t"
        // u = hi - (w - P) in r14:r15; u >= out - slew? (t = out - u <= slew)
        "movw r14, r22\n\t"
        "sub r14, r0\n\t"
        "sbc r15, r1\n\t"
        "movw r0, r24\n\t"
        "sub r0, r14\n\t"
        "sbc r1, r15\n\t"
        "brlt 3f\n\t"
        "cp r8, r0\n\t"
        "cpc r9, r1\n\t"
        "brlo .Lpos_below\n"
        "3:\n\t"  // y = u, saturated = 0
        "movw r24, r14\n\t" PI_RETURN("r21", "r12", "r11", "r10")

            ".Lpos_imax:\n\t"  // I = ilim
            "mov r10, r21\n\t"
            "mov r11, r6\n\t"
            "mov r12, r7\n\t"
            "rjmp .Lpos_i\n"

            ".Lpos_slow:\n\t" PI_SLOW("clr r20\n\t")

                ".Lpos_below:\n\t"  // u < out - slew (> -out_max): y = lo = out - slew if lo <= hi
                "movw r0, r24\n\t"
                "sub r0, r8\n\t"
                "sbc r1, r9\n\t"
                "cp r6, r0\n\t"
                "cpc r7, r1\n\t"
                "brlt .Lpos_slow\n\t"  // lo > out_max >= hi: C
                "movw r24, r0\n\t"
                "ldi r20, 1\n\t" PI_RETURN("r20", "r12", "r11", "r10")

                    ".Lpos_above:\n\t"  // back-calculation: k = hi + out_max (< 0: lo > hi, C)
                    "movw r0, r22\n\t"
                    "add r0, r6\n\t"
                    "adc r1, r7\n\t"
                    "brlt .Lpos_slow\n\t"
                    "sub r0, r15\n\t"  // k - P < 0: c = -out_max, cap = -ilim <= integ
                    "sbc r1, r16\n\t"
                    "brcs .Lpos_prev\n\t"
                    "sub r0, r6\n\t"  // c = hi - P in [-out_max, hi]
                    "sbc r1, r7\n\t"
                    "cp r21, r3\n\t"  // cap = c * 256 < integ?
                    "cpc r0, r4\n\t"
                    "cpc r1, r5\n\t"
                    "brlt .Lpos_prev\n\t"
                    "movw r24, r22\n\t"  // I = cap, u = hi: y = hi, saturated = 0
        PI_RETURN("r21", "r1", "r0", "r21")

            ".Lpos_prev:\n\t"  // I = min(integ, ilim): integ > ilim is C; y = hi
            "cp r21, r3\n\t"
            "cpc r6, r4\n\t"
            "cpc r7, r5\n\t"
            "brlt .Lpos_slow\n\t"
            "movw r0, r22\n\t"  // saturated = P + floor(integ / 256) > hi
            "sub r0, r4\n\t"
            "sbc r1, r5\n\t"
            "ldi r20, 1\n\t"
            "brlt 4f\n\t"
            "sub r0, r15\n\t"
            "sbc r1, r16\n\t"
            "brcs 4f\n\t"
            "clr r20\n"
            "4:\n\t"
            "movw r24, r22\n\t" PI_RETURN_Y("r20")

        // ================= E < 0: rare blocks
        ".Lnm_sat:\n\t"  // e < -65535
        "ldi r18, 0xFF\n\t"
        "ldi r19, 0xFF\n\t"
        "rjmp .Lnm_done\n"  // then a copy of the C call within reach of the first test
        PI_SATS(".Lnp_sat", ".Lnp_done", ".Lnd_sat",
                ".Lnd_done") ".Lneg_slow0:\n\t" PI_SLOW("ldi r20, 1\n\t")

        // ================= E < 0 (P = -pmc, pmc = r15:r16 + (r14 != 0))
        ".Lneg_all:\n\t"  // mag = -e if e >= -65535
        "cpi r20, 0xFF\n\t"
        "cpc r21, r20\n\t"
        "brne .Lnm_sat\n\t"
        "com r19\n\t"
        "neg r18\n\t"
        "sbci r19, 0xFF\n\t"
        "breq .Lnm_sat\n"  // e = -65536
        ".Lnm_done:\n\t"
        "clr r21\n\t" PI_COMMON(".Lnp_sat", ".Lnp_done", ".Lnd_sat", ".Lnd_done")
        // integ <= ilim, else C
        "cp r21, r3\n\t"
        "cpc r6, r4\n\t"
        "cpc r7, r5\n\t"
        "brlt .Lneg_slow0\n\t"
        // I = max(integ - D, -ilim) in place (r3..r5, r20 the top byte); integ = I + D below
        "mov r20, r5\n\t"
        "lsl r20\n\t"
        "sbc r20, r20\n\t"
        "sub r3, r10\n\t"
        "sbc r4, r11\n\t"
        "sbc r5, r12\n\t"
        "sbc r20, r13\n\t"
        "add r4, r6\n\t"  // S + ilim < 0?
        "adc r5, r7\n\t"
        "adc r20, r21\n\t"
        "brmi .Lneg_imin\n\t"
        "sub r4, r6\n\t"
        "sbc r5, r7\n"
        ".Lneg_i:\n\t"
        // lo = max(out - slew, -out_max): r22:r23
        "movw r22, r24\n\t"
        "sub r22, r8\n\t"
        "sbc r23, r9\n\t"
        "brvs 5f\n\t"
        "movw r0, r22\n\t"
        "add r0, r6\n\t"
        "adc r1, r7\n\t"
        "brge 6f\n"
        "5:\n\t"
        "clr r22\n\t"
        "clr r23\n\t"
        "sub r22, r6\n\t"
        "sbc r23, r7\n"
        "6:\n\t"
        // u < lo?  w = floor(I / 256) - lo < 0, or pmc > w
        "movw r0, r4\n\t"
        "sub r0, r22\n\t"
        "sbc r1, r23\n\t"
        "brlt .Lneg_below\n\t"
        "cp r21, r14\n\t"  // carry = (byte 0 of kp * mag != 0): the ceiling
        "sbc r0, r15\n\t"
        "sbc r1, r16\n\t"
        "brcs .Lneg_below\n\t"
        // u = lo + (w - pmc) in r14:r15; u <= out + slew? (t = u - out <= slew)
        "movw r14, r22\n\t"
        "add r14, r0\n\t"
        "adc r15, r1\n\t"
        "movw r0, r14\n\t"
        "sub r0, r24\n\t"
        "sbc r1, r25\n\t"
        "brlt 7f\n\t"
        "cp r8, r0\n\t"
        "cpc r9, r1\n\t"
        "brlo .Lneg_above\n"
        "7:\n\t"  // y = u, saturated = 0
        "movw r24, r14\n\t" PI_RETURN("r21", "r5", "r4", "r3")

            ".Lneg_imin:\n\t"  // I = -ilim; D = (S + ilim) + D = integ + ilim keeps I + D = integ
            "add r10, r3\n\t"
            "adc r11, r4\n\t"
            "adc r12, r5\n\t"
            "clr r3\n\t"
            "clr r4\n\t"
            "clr r5\n\t"
            "sub r4, r6\n\t"
            "sbc r5, r7\n\t"
            "rjmp .Lneg_i\n"

            ".Lneg_slow:\n\t" PI_SLOW("ldi r20, 1\n\t")

                ".Lneg_above:\n\t"  // u > out + slew (< out_max): y = hi = out + slew
                "add r24, r8\n\t"
                "adc r25, r9\n\t"
                "ldi r20, 1\n\t" PI_RETURN("r20", "r5", "r4", "r3")

        // Back-calculation, y = lo; lo <= hi needs lo <= out_max and out >= -out_max (else C).
        ".Lneg_below:\n\t"
        "add r10, r3\n\t"  // integ = I + D: r10..r12
        "adc r11, r4\n\t"
        "adc r12, r5\n\t"
        "movw r0, r6\n\t"  // k = out_max - lo
        "sub r0, r22\n\t"
        "sbc r1, r23\n\t"
        "brlt .Lneg_slow\n\t"
        "movw r4, r24\n\t"
        "add r4, r6\n\t"
        "adc r5, r7\n\t"
        "brlt .Lneg_slow\n\t"
        "cp r21, r14\n\t"  // k - pmc < 0: c = out_max, cap = ilim >= integ
        "sbc r0, r15\n\t"
        "sbc r1, r16\n\t"
        "brcs .Lneg_prev\n\t"
        "movw r4, r6\n\t"  // c = out_max - (k - pmc) = lo + pmc in [lo, out_max]
        "sub r4, r0\n\t"
        "sbc r5, r1\n\t"
        "cp r10, r21\n\t"  // integ < cap = c * 256?
        "cpc r11, r4\n\t"
        "cpc r12, r5\n\t"
        "brlt .Lneg_prev\n\t"
        "movw r24, r22\n\t"  // I = cap, u = lo: y = lo, saturated = 0
        PI_RETURN("r21", "r5", "r4", "r21")

        // I = max(integ, -ilim): integ < -ilim is C; y = lo, saturated = 1 (integ < cap:
        // floor(integ / 256) - pmc <= lo - 1, unlike E > 0).
        ".Lneg_prev:\n\t"
        "mov r0, r11\n\t"
        "mov r1, r12\n\t"
        "add r0, r6\n\t"
        "adc r1, r7\n\t"
        "brlt .Lneg_slow\n\t"
        "movw r24, r22\n\t"
        "ldi r20, 1\n\t" PI_RETURN_Y("r20")::);
}

// The rare cases of pi_step_err_avr (out_max shrunk below the state) end here: a tail jump with
// the arguments in the ABI's registers.
extern "C" int16_t pi_step_mag_slow(pi_state* s, const pi_gains* g, bool neg, uint16_t mag) {
    return pi_step_mag_c(s, g, neg, mag);
}
#endif
