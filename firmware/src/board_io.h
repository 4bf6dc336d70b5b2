// board_io.h - the board layer's functions (PWM, encoders on SPI, UART, tick, EEPROM).
#ifndef BOARD_IO_H
#define BOARD_IO_H

#include <stdint.h>

#include "prm.h"

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
bool uart_rx_pop(uint8_t* byte);
bool uart_rx_take_overflow();  // true once after the RX ring overflowed

void tick_init();
extern volatile uint8_t g_tick_count;  // incremented by the Timer2 compare ISR

extern const prm_eeprom_if g_board_eeprom;

#endif  // BOARD_IO_H
