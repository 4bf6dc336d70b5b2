// cobs.h - Consistent Overhead Byte Stuffing for frames shorter than 254 bytes.
// The encoded form contains no 0x00; the wire adds one 0x00 delimiter after it.
#ifndef COBS_H
#define COBS_H

#include <stdint.h>

// Encoded size of n raw bytes (n <= 253): n + 1.
#define COBS_ENCODED_SIZE(n) ((n) + 1)

// Encode len (<= 253) bytes into out (room for len + 1); returns the encoded length.
uint8_t cobs_encode(const uint8_t* in, uint8_t len, uint8_t* out);

// Decode len encoded bytes (no delimiter) into out (may be the same buffer as in).
// Returns the decoded length, or -1 if the input is not valid COBS (a zero byte, or a code that
// points past the end).
int16_t cobs_decode(const uint8_t* in, uint8_t len, uint8_t* out);

#endif  // COBS_H
