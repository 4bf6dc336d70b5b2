// crc16.h - CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor.
// Check value: crc16_ccitt("123456789") = 0x29B1.
#ifndef CRC16_H
#define CRC16_H

#include <stdint.h>

#define CRC16_INIT 0xFFFFu

uint16_t crc16_update(uint16_t crc, uint8_t byte);
uint16_t crc16_ccitt(const uint8_t* data, uint8_t len);

#endif  // CRC16_H
