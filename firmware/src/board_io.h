// board_io.h - the board layer's functions (PWM, encoders on SPI, UART, tick, EEPROM).
#ifndef BOARD_IO_H
#define BOARD_IO_H

#include <stdint.h>

#include "board.h"
#include "params.h"

// Every output that can move a motor off: the driver enables driven low, the PWM compare outputs
// disconnected from their pins (TCCRnA = 0) and those pins driven low. Inline with constant
// addresses only, so that it runs in .init3 (before .data and .bss exist) and in the tick
// interrupt alike.
static inline __attribute__((always_inline)) void board_outputs_off() {
    BOARD_EN_PORT &= static_cast<uint8_t>(~BOARD_EN_MASK);
    BOARD_EN_DDR |= BOARD_EN_MASK;
    TCCR1A = 0;
    TCCR3A = 0;
    TCCR4A = 0;
    TCCR5A = 0;
    TCCR0A = 0;
    BOARD_M0_PORT &= static_cast<uint8_t>(~BOARD_M0_PINS);
    BOARD_M0C_PORT &= static_cast<uint8_t>(~BOARD_M0C_PINS);
    BOARD_M1_PORT &= static_cast<uint8_t>(~BOARD_M1_PINS);
    BOARD_M2_PORT &= static_cast<uint8_t>(~BOARD_M2_PINS);
    BOARD_M3_PORT &= static_cast<uint8_t>(~BOARD_M3_PINS);
    BOARD_M0_DDR |= BOARD_M0_PINS;
    BOARD_M0C_DDR |= BOARD_M0C_PINS;
    BOARD_M1_DDR |= BOARD_M1_PINS;
    BOARD_M2_DDR |= BOARD_M2_PINS;
    BOARD_M3_DDR |= BOARD_M3_PINS;
}

// Timers set up and started together (phase-aligned), compare values 0, outputs connected. The
// pins are outputs already (board_outputs_off in .init3).
void pwm_init();
// duty: compare values 0..BOARD_PWM_TOP per wheel and phase; enable_mask bit w enables wheel w.
void pwm_apply(const uint16_t duty[][3], uint8_t enable_mask);

void spi_init();
// Read one encoder (chip-select bit cs_bit of BOARD_CS_PORT) into words[0].
void enc_read_one(uint16_t words[1], uint8_t cs_bit);
// Send ENC_CMD_CLEAR_ERROR to every encoder whose bit (0..3 = M0..M3) is set in mask.
void enc_clear_errors(uint8_t mask);

void uart_init();
bool uart_tx_frame(const uint8_t* data, uint8_t len);  // whole frame or nothing, never blocks
// The RX ring (board_uart.cpp): the oldest received byte without taking it, then taking it.
// Inline: the main loop reads up to 100 bytes a tick at 1 Mbaud.
extern "C" {
extern volatile uint8_t board_rx_buf[BOARD_UART_RX_SIZE];
extern volatile uint8_t board_rx_head;
extern volatile uint8_t board_rx_tail;
}
static inline bool uart_rx_peek(uint8_t* byte) {
    const uint8_t t = board_rx_tail;
    if (t == board_rx_head) return false;
    *byte = board_rx_buf[t];
    return true;
}
static inline void uart_rx_next() {
    board_rx_tail = static_cast<uint8_t>(board_rx_tail + 1);
}
// The TX interrupt is held off (the bytes wait in the ring) from the tick (the tick interrupt
// clears UDRIE0 and sets board_tx_held; uart_tx_frame leaves it off) to the end of the control
// step, so that only the RX interrupts stretch the tick-to-step time during a full-duplex burst:
// the end of a dispatch running when the tick comes, then the step.
extern "C" volatile uint8_t board_tx_held;
static inline void uart_tx_release() {
    board_tx_held = 0;
    UCSR0B |= _BV(UDRIE0);  // an empty ring: the interrupt clears it again at once
}
// True once after the RX ring overflowed. Inline: the main loop asks on every pass.
extern "C" volatile uint8_t board_rx_overflow;
static inline bool uart_rx_take_overflow() {
    if (!board_rx_overflow) return false;
    board_rx_overflow = 0;
    return true;
}
// STOP_ALL frames the receive interrupt has seen whole (board_uart.cpp), free-running; each frame
// also goes through the ring and is dispatched (and acknowledged) in order.
uint8_t uart_stops_seen();

void tick_init();
extern volatile uint8_t g_tick_count;  // incremented by the Timer2 compare ISR
// Ticks since the last completed control step: the tick ISR counts, the main loop zeroes it after
// each step (board.h, BOARD_HANG_TICKS).
extern volatile uint8_t g_ticks_since_step;
// BOARD_WDT_MARK when the tick ISR found the main loop hung (.noinit: kept across the reset).
extern uint32_t g_wdt_mark;

extern const prm_eeprom_if g_board_eeprom;

#endif  // BOARD_IO_H
