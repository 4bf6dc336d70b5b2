#include "enc.h"

bool enc_even_parity(uint16_t word) {
    uint8_t x = static_cast<uint8_t>(word ^ (word >> 8));
    x ^= static_cast<uint8_t>(x >> 4);
    x ^= static_cast<uint8_t>(x >> 2);
    x ^= static_cast<uint8_t>(x >> 1);
    return (x & 1u) == 0;
}

enc_status enc_parse(uint16_t word, uint16_t* angle) {
    if (!enc_even_parity(word)) return ENC_PARITY;
    if (word & 0x4000u) return ENC_ERROR;
    *angle = static_cast<uint16_t>(word & ENC_MASK);
    return ENC_OK;
}

uint16_t enc_make_reply(uint16_t angle, bool error_flag) {
    uint16_t w = static_cast<uint16_t>(angle & ENC_MASK);
    if (error_flag) w = static_cast<uint16_t>(w | 0x4000u);
    if (!enc_even_parity(w)) w = static_cast<uint16_t>(w | 0x8000u);
    return w;
}
