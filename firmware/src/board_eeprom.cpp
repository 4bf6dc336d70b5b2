// board_eeprom.cpp - the parameter store's EEPROM interface on the ATmega2560 registers.
// Writes never wait: the store calls write() only when ready() says the last write is done.
#include <avr/interrupt.h>

#include "board.h"
#include "board_io.h"

static uint8_t ee_read(uint16_t addr) {
    while (EECR & _BV(EEPE)) {
    }
    EEAR = addr;
    EECR |= _BV(EERE);
    return EEDR;
}

static bool ee_ready() {
    return (EECR & _BV(EEPE)) == 0;
}

static void ee_write(uint16_t addr, uint8_t value) {
    EEAR = addr;
    EEDR = value;
    uint8_t sreg = SREG;
    cli();  // EEPE must follow EEMPE within 4 cycles
    EECR |= _BV(EEMPE);
    EECR |= _BV(EEPE);
    SREG = sreg;
}

const prm_eeprom_if g_board_eeprom = {ee_read, ee_ready, ee_write};
