// port_progmem.h - the one portability shim of the portable firmware logic.
// On AVR, constant tables live in flash (PROGMEM) and are read with pgm_read_word; on the host
// they are plain const arrays. No other file in firmware/lib/ may include an AVR header.
#ifndef PORT_PROGMEM_H
#define PORT_PROGMEM_H

#include <stdint.h>

#if defined(__AVR__)
#include <avr/pgmspace.h>
#define PORT_PROGMEM PROGMEM
#define PORT_READ_I16(addr) (static_cast<int16_t>(pgm_read_word(addr)))
#else
#define PORT_PROGMEM
#define PORT_READ_I16(addr) (*(addr))
#endif

#endif  // PORT_PROGMEM_H
