// board_tick.cpp - 1 kHz control tick on Timer2 (CTC). The ISR counts and holds the TX interrupt
// (board_io.h); the main loop runs the control step when the count changes and reports skipped
// counts as overruns.
#include <avr/interrupt.h>

#include "board.h"
#include "board_io.h"

volatile uint8_t g_tick_count;
volatile uint8_t g_ticks_since_step;
// Kept across resets (.noinit is neither loaded nor cleared at start-up). The stock bootloader
// uses the bottom of RAM for its few globals and the top for its stack (a 285-byte message
// buffer), not the addresses after the application's .bss where this lies.
uint32_t g_wdt_mark __attribute__((section(".noinit")));

// The main loop has completed no step for BOARD_HANG_TICKS ticks: every output off, the mark for
// the next boot, and wait (interrupts off) for the watchdog's reset.
static inline __attribute__((always_inline, noreturn)) void tick_hung() {
    board_outputs_off();
    g_wdt_mark = BOARD_WDT_MARK;
    for (;;) {
    }
}

void tick_init() {
    TCCR2A = BOARD_TICK_TCCRA;
    OCR2A = BOARD_TICK_OCR;
    TCNT2 = 0;
    TIMSK2 = _BV(OCIE2A);
    TCCR2B = BOARD_TICK_TCCRB;
}

// TIMER2_COMPA: also holds the TX interrupt until the step is done (uart_tx_release, board_io.h)
// and finds a hung main loop (board.h, BOARD_HANG_TICKS).
ISR(TIMER2_COMPA_vect) {
    g_tick_count = static_cast<uint8_t>(g_tick_count + 1);
    UCSR0B &= static_cast<uint8_t>(~_BV(UDRIE0));
    board_tx_held = 1;
    const uint8_t late = static_cast<uint8_t>(g_ticks_since_step + 1);
    g_ticks_since_step = late;
    if (late >= BOARD_HANG_TICKS) tick_hung();
}
