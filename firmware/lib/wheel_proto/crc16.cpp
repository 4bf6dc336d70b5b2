#include "crc16.h"

uint16_t crc16_ccitt(const uint8_t* data, uint8_t len) {
    uint16_t crc = CRC16_INIT;
    for (uint8_t i = 0; i < len; i++) crc = crc16_update(crc, data[i]);
    return crc;
}
