#include "enc.h"

uint16_t enc_make_reply(uint16_t angle, bool error_flag) {
    uint16_t w = static_cast<uint16_t>(angle & ENC_MASK);
    if (error_flag) w = static_cast<uint16_t>(w | 0x4000u);
    if (!enc_even_parity(w)) w = static_cast<uint16_t>(w | 0x8000u);
    return w;
}
