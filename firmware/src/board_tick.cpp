// board_tick.cpp - 1 kHz control tick on Timer2 (CTC). The ISR counts and holds the TX interrupt
// (board_io.h); the main loop runs the control step when the count changes and reports skipped
// counts as overruns.
#include <avr/interrupt.h>

#include "board.h"
#include "board_io.h"

volatile uint8_t g_tick_count;

void tick_init() {
    TCCR2A = BOARD_TICK_TCCRA;
    OCR2A = BOARD_TICK_OCR;
    TCNT2 = 0;
    TIMSK2 = _BV(OCIE2A);
    TCCR2B = BOARD_TICK_TCCRB;
}

// TIMER2_COMPA: also holds the TX interrupt until the step is done (uart_tx_release, board_io.h).
// 37 cycles first instruction to reti + 8 entry = 45 (simavr, make -C firmware cycles).
ISR(TIMER2_COMPA_vect) {
    g_tick_count = static_cast<uint8_t>(g_tick_count + 1);
    UCSR0B &= static_cast<uint8_t>(~_BV(UDRIE0));
    board_tx_held = 1;
}
