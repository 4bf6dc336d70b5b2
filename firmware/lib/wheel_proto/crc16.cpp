#include "crc16.h"

uint16_t crc16_update(uint16_t crc, uint8_t byte) {
    // Byte-wise form of the bit-serial 0x1021 division without a table (no flash, few cycles).
    uint8_t x = static_cast<uint8_t>((crc >> 8) ^ byte);
    x ^= static_cast<uint8_t>(x >> 4);
    return static_cast<uint16_t>((crc << 8) ^ (static_cast<uint16_t>(x) << 12) ^
                                 (static_cast<uint16_t>(x) << 5) ^ x);
}

uint16_t crc16_ccitt(const uint8_t* data, uint8_t len) {
    uint16_t crc = CRC16_INIT;
    for (uint8_t i = 0; i < len; i++) crc = crc16_update(crc, data[i]);
    return crc;
}
