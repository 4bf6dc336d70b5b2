/*
 * selftest.c - a tiny ATmega2560 program that exercises every interface of the FIL harness,
 * independent of the real firmware: fast PWM mode 14 on Timers 1/3/4/5 (M0's phase C on Timer0
 * OC0B, mode 7, TOP 99, as the wheel board's pin map has it), enables PA0..PA3,
 * AS5048A reads over SPI with chip selects PA4..PA7, a 1 kHz Timer2 tick bracketed by
 * GPIOR0 = 1 / 0, and UART0 at 500 kbaud.
 *
 * Each motor is stepped open loop (a rotating voltage vector) with its own speed profile,
 * ramped over 1.024 s: M0 +100 rpm, M1 -100 rpm, M2 +200 rpm, M3 held at 0 rpm.
 * Every 10 ticks it prints "A <tick> <raw0> <raw1> <raw2> <raw3>" (raw 16-bit AS5048A words,
 * hex); every byte received is echoed back as "E <hex>".
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <math.h>
#include <stdint.h>

#define TOP 799
#define AMPL 300
#define POLE_PAIRS 7

static int16_t sine_table[256];
static volatile uint8_t tick_flag;
static const int16_t target_rpm[4] = {100, -100, 200, 0};
static uint32_t phase[4];   /* electrical angle, 256 << 16 per turn */
static uint16_t raw[4];     /* last AS5048A answers */
static int32_t full_inc[4]; /* phase increment per tick at full speed */

ISR(TIMER2_COMPA_vect) {
    tick_flag = 1;
}

static void uart_putc(char c) {
    while (!(UCSR0A & _BV(UDRE0))) {
    }
    UDR0 = c;
}

static void uart_hex(uint16_t v, uint8_t digits) {
    static const char hex[] = "0123456789abcdef";
    while (digits--) uart_putc(hex[(v >> (4 * digits)) & 0xF]);
}

static uint8_t spi_xfer(uint8_t b) {
    SPDR = b;
    while (!(SPSR & _BV(SPIF))) {
    }
    return SPDR;
}

static uint16_t encoder_read(uint8_t m) {
    uint8_t cs = _BV(PA4 + m);
    PORTA &= ~cs;
    uint16_t w = (uint16_t)spi_xfer(0xFF) << 8;
    w |= spi_xfer(0xFF);
    PORTA |= cs;
    return w;
}

static void set_duties(volatile uint16_t* ocr_a, volatile uint16_t* ocr_b, volatile uint16_t* ocr_c,
                       uint32_t ph) {
    /* cosine pattern: the voltage vector points at the phase angle itself */
    uint8_t i = (uint8_t)((ph >> 16) + 64);
    *ocr_a = (uint16_t)(TOP / 2 + (int16_t)(((int32_t)AMPL * sine_table[i]) >> 15));
    *ocr_b = (uint16_t)(TOP / 2 + (int16_t)(((int32_t)AMPL * sine_table[(uint8_t)(i - 85)]) >> 15));
    *ocr_c =
        (uint16_t)(TOP / 2 + (int16_t)(((int32_t)AMPL * sine_table[(uint8_t)(i - 171)]) >> 15));
}

static void pwm_init(volatile uint8_t* tccra, volatile uint8_t* tccrb, volatile uint16_t* icr) {
    *icr = TOP;
    *tccra = _BV(COM1A1) | _BV(COM1B1) | _BV(COM1C1) | _BV(WGM11);
    *tccrb = _BV(WGM13) | _BV(WGM12) | _BV(CS10);
}

int main(void) {
    for (uint16_t i = 0; i < 256; i++) sine_table[i] = (int16_t)(32767.0 * sin(i * M_PI / 128.0));
    for (uint8_t m = 0; m < 4; m++) {
        /* phase increment per tick = rpm * pp * 256 * 65536 / 60000 */
        full_inc[m] = (int32_t)((int64_t)target_rpm[m] * POLE_PAIRS * 256 * 65536 / 60000);
    }
    DDRA = 0xFF;
    PORTA = 0xF0; /* chip selects high, enables low */
    DDRB = _BV(PB0) | _BV(PB1) | _BV(PB2) | _BV(PB5) | _BV(PB6);
    DDRG = _BV(PG5);
    SPCR = _BV(SPE) | _BV(MSTR) | _BV(CPHA) | _BV(SPR0);
    pwm_init(&TCCR1A, &TCCR1B, &ICR1);
    OCR0A = (TOP + 1) / 8 - 1; /* 20 kHz at clk/8 */
    TCCR0A = _BV(COM0B1) | _BV(WGM01) | _BV(WGM00);
    TCCR0B = _BV(WGM02) | _BV(CS01);
    pwm_init(&TCCR3A, &TCCR3B, &ICR3);
    pwm_init(&TCCR4A, &TCCR4B, &ICR4);
    pwm_init(&TCCR5A, &TCCR5B, &ICR5);
    UBRR0 = 1; /* 500 kbaud at 16 MHz */
    UCSR0B = _BV(RXEN0) | _BV(TXEN0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
    OCR2A = 249; /* 16 MHz / 64 / 250 = 1 kHz */
    TCCR2A = _BV(WGM21);
    TCCR2B = _BV(CS22);
    TIMSK2 = _BV(OCIE2A);
    PORTA |= 0x0F; /* enable all four bridges */
    sei();

    uint32_t tick = 0;
    for (;;) {
        if (UCSR0A & _BV(RXC0)) {
            uint8_t c = UDR0;
            uart_putc('E');
            uart_putc(' ');
            uart_hex(c, 2);
            uart_putc('\n');
        }
        if (!tick_flag) continue;
        tick_flag = 0;
        GPIOR0 = 1;
        for (uint8_t m = 0; m < 4; m++) raw[m] = encoder_read(m);
        /* speed ramps linearly to its target over the first second */
        int32_t ramp = tick < 1024 ? (int32_t)tick : 1024;
        for (uint8_t m = 0; m < 4; m++) {
            phase[m] += (uint32_t)((full_inc[m] >> 10) * ramp);
        }
        uint16_t m0c;
        set_duties(&OCR1A, &OCR1B, &m0c, phase[0]);
        OCR0B = (uint8_t)(m0c >> 3);
        set_duties(&OCR3A, &OCR3B, &OCR3C, phase[1]);
        set_duties(&OCR4A, &OCR4B, &OCR4C, phase[2]);
        set_duties(&OCR5A, &OCR5B, &OCR5C, phase[3]);
        GPIOR0 = 0;
        tick++;
        if (tick % 10 == 0) {
            uart_putc('A');
            uart_putc(' ');
            uart_hex((uint16_t)(tick >> 16), 4);
            uart_hex((uint16_t)tick, 4);
            for (uint8_t m = 0; m < 4; m++) {
                uart_putc(' ');
                uart_hex(raw[m], 4);
            }
            uart_putc('\n');
        }
    }
}
