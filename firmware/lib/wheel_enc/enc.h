// enc.h - AS5048A 14-bit magnetic encoder frames (SPI mode 1, 16-bit words).
//
// Read sequence used by the board layer, per encoder and per control tick:
//   transaction 1: send ENC_CMD_READ_ANGLE (0xFFFF), ignore the reply (it answers the previous
//   one); CS high for at least 350 ns; transaction 2: send ENC_CMD_READ_ANGLE again, the reply
//   carries the angle latched at the end of transaction 1. The angle is therefore fresh (a few
//   microseconds old), not one tick old.
// Reply word: bit 15 even parity over bits 14..0, bit 14 error flag, bits 13..0 angle.
// After a bad reply (error flag or parity) the application asks the board to send
// ENC_CMD_CLEAR_ERROR to that encoder after the step (app_state.enc_clear), so a transient error
// costs one sample; ENC_FAULT_LIMIT consecutive bad replies latch the encoder fault.
#ifndef ENC_H
#define ENC_H

#include <stdint.h>

#include "port_progmem.h"

#define ENC_COUNTS 16384u
#define ENC_MASK 0x3FFFu
#define ENC_CMD_READ_ANGLE 0xFFFFu
// Read of the CLEAR ERROR FLAG register (address 0x0001, read bit 14, even parity bit 15 = 0):
// the reply in the next frame is the error register, and reading it clears the sensor's error flag
// (which otherwise stays set in every reply).
#define ENC_CMD_CLEAR_ERROR 0x4001u

enum enc_status : uint8_t {
    ENC_OK = 0,
    ENC_PARITY = 1,  // parity bit does not match: corrupted word
    ENC_ERROR = 2,   // error flag set by the sensor (previous command failed)
};

// Even parity of a 16-bit word: true if the number of set bits is even.
PORT_INLINE bool enc_even_parity(uint16_t word) {
    uint8_t x = static_cast<uint8_t>(word ^ (word >> 8));
    x ^= static_cast<uint8_t>(x >> 4);
    x ^= static_cast<uint8_t>(x >> 2);
    x ^= static_cast<uint8_t>(x >> 1);
    return (x & 1u) == 0;
}

// Decode one reply word; on ENC_OK stores the 14-bit angle in *angle. Inline: it runs for every
// wheel in every control step.
PORT_INLINE enc_status enc_parse(uint16_t word, uint16_t* angle) {
    if (!enc_even_parity(word)) return ENC_PARITY;
    if (word & 0x4000u) return ENC_ERROR;
    *angle = static_cast<uint16_t>(word & ENC_MASK);
    return ENC_OK;
}

// Build a valid reply word for an angle (used by tests and simulations).
uint16_t enc_make_reply(uint16_t angle, bool error_flag);

#endif  // ENC_H
