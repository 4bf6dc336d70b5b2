// port_check.cpp - runs on the ATmega2560 in simavr: compares the assembly of the control step
// with C computed by avr-gcc's own 32-bit arithmetic: the multiplies of port_progmem.h over the
// operand extremes and a sweep, and the PI (pi_step_err_avr, 24-bit integrator) with its C
// reference pi_step_err_c over gain, limit and error extremes and random sequences. The native
// tests cannot see 24-bit overflow; this runs the AVR code itself. Prints "port-check: N
// mismatches in M checks" on UART0 and stops (`make -C firmware port-check` fails unless N is 0).
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <stdint.h>

#include "pi.h"
#include "port_progmem.h"

static void put(char c) {
    while (!(UCSR0A & _BV(UDRE0))) {
    }
    UDR0 = c;
}

static void put_u32(uint32_t v) {
    char d[10];
    uint8_t n = 0;
    do {
        d[n++] = static_cast<char>('0' + v % 10);
        v /= 10;
    } while (v);
    while (n) put(d[--n]);
}

// Reference products through volatile int32 operands: avr-gcc's __mulsi3, not the asm.
static volatile int32_t g_sa, g_sb;
static volatile uint32_t g_ua, g_ub;

static uint32_t g_bad, g_n;

static void check(uint16_t a, uint16_t b) {
    g_n += 5;
    g_ua = a;
    g_ub = b;
    if (port_mul_u16(a, b) != g_ua * g_ub) g_bad++;
    g_sa = static_cast<int16_t>(a);
    g_sb = static_cast<int16_t>(b);
    int32_t s = port_mul_s16(static_cast<int16_t>(a), static_cast<int16_t>(b));
    if (s != g_sa * g_sb) g_bad++;
    if (port_mulhi_s16(static_cast<int16_t>(a), static_cast<int16_t>(b)) !=
        static_cast<int16_t>((g_sa * g_sb) >> 16)) {
        g_bad++;
    }
    if (port_mulhi_u16(a, b) != static_cast<uint16_t>((g_ua * g_ub) >> 16)) g_bad++;
    // port_mul_s24_u8: a signed 24-bit operand (a with b's low byte as the top byte, sign-
    // extended) times the low byte of b.
    g_sa = static_cast<int32_t>(static_cast<uint32_t>(static_cast<int8_t>(b >> 8)) << 16) | a;
    g_sb = static_cast<uint8_t>(b);
    if (port_mul_s24_u8(g_sa, static_cast<uint8_t>(b)) != g_sa * g_sb) g_bad++;
}

static uint32_t g_rnd = 1;
static uint16_t rnd16() {
    g_rnd = g_rnd * 1664525u + 1013904223u;
    return static_cast<uint16_t>(g_rnd >> 12);
}

static uint32_t g_pi_bad, g_pi_n;

// The same PI step in assembly and in C from the same state: output, integrator and flag.
static void check_pi(pi_state* sa, pi_state* sc, const pi_gains* g, int32_t e) {
    g_n++;
    g_pi_n++;
    int16_t ya = pi_step_err(sa, g, e);  // the call the control step makes
    int16_t yc = pi_step_err_c(sc, g, e);
    if (ya != yc || static_cast<int32_t>(sa->integ) != static_cast<int32_t>(sc->integ) ||
        sa->out != sc->out || sa->saturated != sc->saturated) {
        g_bad++;
        g_pi_bad++;
        *sa = *sc;  // go on from the reference state
    }
}

static int32_t rnd32() {
    return static_cast<int32_t>((static_cast<uint32_t>(rnd16()) << 16) ^ rnd16());
}

// Runs from a reset state over gain, limit and error extremes: errors at the clamp and the int32
// ends, random, and held constant for a whole run (the integrator winds up to the limits and the
// back-calculation holds it there, as in the cycle bench); out_max shrinks or grows and ki
// changes while running.
static void check_pi_all() {
    static const uint16_t gains[] = {0, 1, 2, 80, 120, 255, 256, 1000, 32767, 32768, 40000, 65535};
    static const int16_t limits[] = {0, 1, 100, 10000, 16384, 32767};
    static const int32_t errs[] = {
        0,          1,           -1,
        2,          -2,          255,
        -256,       59,          -59,
        65534,      -65534,      65535,
        -65535,     65536,       -65536,
        65537,      -65537,      100000,
        -100000,    16777216,    -16777216,
        2147483647, -2147483647, -2147483647 - 1};  // INT32_MIN too (outside the contract)
    const uint8_t ne = sizeof errs / sizeof errs[0];
    for (uint16_t run = 0; run < 3000; run++) {
        pi_gains g = {gains[rnd16() % 12], gains[rnd16() % 12], limits[rnd16() % 6],
                      static_cast<int16_t>(1 + (rnd16() & 0x7FFF) % 32767)};
        if (run % 3 == 0) g.slew = limits[1 + rnd16() % 5];
        const uint8_t mode = static_cast<uint8_t>(run & 3);
        const int32_t held =
            (rnd16() & 1) ? errs[rnd16() % ne] : static_cast<int32_t>(rnd16() % 2001) - 1000;
        const uint8_t steps = mode == 3 ? 200 : 50;
        pi_state sa, sc;
        pi_reset(&sa);
        pi_reset(&sc);
        for (uint8_t k = 0; k < steps; k++) {
            if (k == 25 || k == 150) g.out_max = limits[rnd16() % 6];  // shrinks or grows
            if (k == 35) g.ki_q8 = gains[rnd16() % 12];
            if (k == 100 && (rnd16() & 1)) g.slew = limits[1 + rnd16() % 5];
            int32_t e;
            const uint16_t r = rnd16();
            if (mode >= 2 && (r & 15) != 0) {
                e = (k >= 120 && (r & 16)) ? -held : held;  // held, reversed late in long runs
            } else if ((r & 3) == 0) {
                e = errs[rnd16() % ne];
            } else if ((r & 3) == 1) {
                e = rnd32();
            } else {
                e = static_cast<int32_t>(rnd16() % 40001) - 20000;
            }
            check_pi(&sa, &sc, &g, e);
        }
    }
}

int main() {
    UBRR0 = 3;
    UCSR0A = _BV(U2X0);
    UCSR0B = _BV(TXEN0);
    static const uint16_t edge[] = {0,      1,      2,      0x7F,   0x80,   0xFF,   0x100,
                                    0x7FFF, 0x8000, 0x8001, 0xFF00, 0xFFFE, 0xFFFF, 1838,
                                    32639,  54685,  918,    0x00FF, 0x0101};
    const uint8_t ne = sizeof edge / sizeof edge[0];
    for (uint8_t i = 0; i < ne; i++) {
        for (uint8_t j = 0; j < ne; j++) check(edge[i], edge[j]);
    }
    for (uint32_t a = 0; a < 65536u; a += 251) {
        for (uint32_t b = 0; b < 65536u; b += 4093) {
            check(static_cast<uint16_t>(a), static_cast<uint16_t>(b));
        }
    }
    check_pi_all();
    const char* msg = "port-check: ";
    while (*msg) put(*msg++);
    put_u32(g_bad);
    msg = " mismatches in ";
    while (*msg) put(*msg++);
    put_u32(g_n);
    msg = " checks (PI: ";
    while (*msg) put(*msg++);
    put_u32(g_pi_bad);
    msg = " in ";
    while (*msg) put(*msg++);
    put_u32(g_pi_n);
    msg = ")\n";
    while (*msg) put(*msg++);
    while (!(UCSR0A & _BV(TXC0))) {
    }
    cli();
    sleep_cpu();
}
