// port_check.cpp - runs on the ATmega2560 in simavr: compares the inline-assembly multiplies of
// port_progmem.h with the same products computed by avr-gcc's own 32-bit arithmetic, over the
// operand extremes and a sweep. Prints "port-check: N mismatches in M products" on UART0 and stops
// (`make -C firmware port-check` fails unless N is 0).
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <stdint.h>

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
    g_n += 3;
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
    const char* msg = "port-check: ";
    while (*msg) put(*msg++);
    put_u32(g_bad);
    msg = " mismatches in ";
    while (*msg) put(*msg++);
    put_u32(g_n);
    msg = " products\n";
    while (*msg) put(*msg++);
    while (!(UCSR0A & _BV(TXC0))) {
    }
    cli();
    sleep_cpu();
}
