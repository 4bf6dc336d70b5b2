// board.h - every pin and register of the wheel board (Arduino Mega 2560, ATmega2560 @ 16 MHz).
// The pin map is fixed in docs/hardware.md; the simavr harness (firmware/sim/) relies on it.
#ifndef BOARD_H
#define BOARD_H

#include <avr/io.h>
#include <stdint.h>

#define BOARD_WHEELS 4

// ---- Motor phases: hardware PWM at 20 kHz, phase-aligned (the timers start together, board_pwm).
// Timers 1/3/4/5: fast PWM mode 14 (TOP = ICRn), prescaler 1, compare values 0..BOARD_PWM_TOP.
// M0 phase C is on Timer0 (8-bit), not on OC1C: OC1C is PB7 (D13), the Mega's LED, which the
// stock bootloader drives and blinks at every reset. The twelve 16-bit compare outputs are
// exactly the twelve phases, and OC1C has no other pin, so one phase has to go to an 8-bit
// timer: Timer0 fast PWM mode 7 (TOP = OCR0A = 99), prescaler 8, 16 MHz / 8 / 100 = 20 kHz;
// its compare value is the phase's 0..799 value >> 3 (steps of 8 counts, 1 % of the supply).
// M0 Timer1: OC1A PB5 (D11), OC1B PB6 (D12); Timer0: OC0B PG5 (D4)
// M1 Timer3: OC3A PE3 (D5),  OC3B PE4 (D2),  OC3C PE5 (D3)
// M2 Timer4: OC4A PH3 (D6),  OC4B PH4 (D7),  OC4C PH5 (D8)
// M3 Timer5: OC5A PL3 (D46), OC5B PL4 (D45), OC5C PL5 (D44)
#define BOARD_PWM_TOP 799
#define BOARD_PWM0_TOP 99
#define BOARD_PWM0_SHIFT 3  // (BOARD_PWM_TOP + 1) / (BOARD_PWM0_TOP + 1) = 2^3
#define BOARD_M0_PORT PORTB
#define BOARD_M0_DDR DDRB
#define BOARD_M0_PINS (_BV(PB5) | _BV(PB6))
#define BOARD_M0C_PORT PORTG
#define BOARD_M0C_DDR DDRG
#define BOARD_M0C_PINS _BV(PG5)
#define BOARD_M1_PORT PORTE
#define BOARD_M1_DDR DDRE
#define BOARD_M1_PINS (_BV(PE3) | _BV(PE4) | _BV(PE5))
#define BOARD_M2_PORT PORTH
#define BOARD_M2_DDR DDRH
#define BOARD_M2_PINS (_BV(PH3) | _BV(PH4) | _BV(PH5))
#define BOARD_M3_PORT PORTL
#define BOARD_M3_DDR DDRL
#define BOARD_M3_PINS (_BV(PL3) | _BV(PL4) | _BV(PL5))
// TCCRnA: non-inverting on A/B/C, WGMn1; TCCRnB: WGMn3 | WGMn2 | CSn0 (mode 14, clk/1).
#define BOARD_PWM_TCCRA(n) (_BV(COM##n##A1) | _BV(COM##n##B1) | _BV(COM##n##C1) | _BV(WGM##n##1))
#define BOARD_PWM_TCCRB(n) (_BV(WGM##n##3) | _BV(WGM##n##2) | _BV(CS##n##0))
// Timer0: non-inverting on B only (OC0A, PB7, stays a plain port pin), mode 7, clk/8.
#define BOARD_PWM0_TCCRA (_BV(COM0B1) | _BV(WGM01) | _BV(WGM00))
#define BOARD_PWM0_TCCRB (_BV(WGM02) | _BV(CS01))

// ---- Driver enables M0..M3: PA0..PA3 (D22..D25), active high. Every enable needs a pull-down
// (10 kOhm to GND, docs/hardware.md): the pins float from reset through the bootloader (about
// 1 s after a power-on or DTR reset) until main_early_init drives them low.
#define BOARD_EN_PORT PORTA
#define BOARD_EN_DDR DDRA
#define BOARD_EN_SHIFT 0
#define BOARD_EN_MASK 0x0Fu

// ---- Encoders: AS5048A on SPI (mode 1, MSB first, clk/2 = 8 MHz with SPI2X; the sensor allows
// 10 MHz). On long encoder leads set BOARD_SPI_SPSR to 0 (clk/4 = 4 MHz): every byte of the
// control step's encoder reads then takes 32 instead of 16 cycles (about 100 more per step).
// SPI master pins: PB0 SS (D53, kept as output so the SPI stays master), PB1 SCK (D52),
// PB2 MOSI (D51), PB3 MISO (D50). Chip selects M0..M3: PA4..PA7 (D26..D29), active low.
#define BOARD_SPI_DDR DDRB
#define BOARD_SPI_OUT_PINS (_BV(PB0) | _BV(PB1) | _BV(PB2))
// MISO pulled up: a line no sensor drives (cable off, sensor dead) reads 0xFFFF, whose error
// flag the step counts as a bad word, instead of a floating level.
#define BOARD_SPI_PORT PORTB
#define BOARD_SPI_MISO_PULLUP _BV(PB3)
#define BOARD_SPI_SPCR (_BV(SPE) | _BV(MSTR) | _BV(CPHA))
#define BOARD_SPI_SPSR _BV(SPI2X)
#define BOARD_CS_PORT PORTA
#define BOARD_CS_DDR DDRA
#define BOARD_CS_SHIFT 4
#define BOARD_CS_MASK 0xF0u

// ---- Control tick: Timer2 CTC, clk/64, OCR2A = 249 -> 1 kHz; TCNT2 counts 4 us steps.
#define BOARD_TICK_TCCRA _BV(WGM21)
#define BOARD_TICK_TCCRB _BV(CS22)
#define BOARD_TICK_OCR 249
#define BOARD_TICK_US_PER_COUNT 4

// ---- Watchdog: plain system-reset mode, 16 ms (WDE, WDP = 0), kicked after every completed
// control step only: any hang, interrupts on or off, resets the chip within 16 ms of the last
// step, and the reset switches every output off (pins inputs, enables held low by their
// pull-downs) until main_early_init drives them low. The tick interrupt also counts ticks without
// a completed step: at BOARD_HANG_TICKS it switches every output off, leaves BOARD_WDT_MARK in a
// .noinit word and waits for the reset. The mark tells the next boot that the watchdog reset it
// when MCUSR cannot: the stock Mega bootloader (stk500v2) clears MCUSR before it starts the
// application and passes nothing on. A hang with interrupts off, or with Timer2 stopped, leaves
// no mark: behind that bootloader its cause is lost (docs/hardware.md).
#define BOARD_WDT_MARK 0x57444F47UL  // "WDOG"
#define BOARD_HANG_TICKS 8u          // ticks without a step: half the watchdog's 16 ms

// ---- Host link: UART0 (D0 RX, D1 TX via the USB bridge), 1000000 baud exact: U2X, UBRR0 = 1.
// A 38-byte telemetry frame takes 380 us, so it is sent before the next control step starts
// and its TX interrupts do not preempt the step (at 500 kbaud they did, about 330 cycles a step).
#define BOARD_UART_UBRR 1
#define BOARD_UART_RX_SIZE 256  // free-running 8-bit indices
#define BOARD_UART_TX_SIZE 256  // free-running 8-bit indices

// ---- Cycle measurement: GPIOR0 = 1 just before the control step of all wheels, 0 right after;
// GPIOR1 = 1 while the main loop works on a tick (step, PWM, telemetry frame), 0 after it;
// GPIOR2 = 1 around the telemetry call (a frame built and queued on every TELEMETRY_DIV-th tick).
#define BOARD_CYCLE_MARK GPIOR0
#define BOARD_TICK_MARK GPIOR1
#define BOARD_TELEM_MARK GPIOR2

#endif  // BOARD_H
