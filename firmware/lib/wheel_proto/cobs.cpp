#include "cobs.h"

uint8_t cobs_encode(const uint8_t* in, uint8_t len, uint8_t* out) {
    uint8_t code_pos = 0;
    uint8_t code = 1;
    uint8_t o = 1;
    for (uint8_t i = 0; i < len; i++) {
        if (in[i] == 0) {
            out[code_pos] = code;
            code_pos = o++;
            code = 1;
        } else {
            out[o++] = in[i];
            code++;
        }
    }
    out[code_pos] = code;
    return o;
}

int16_t cobs_decode(const uint8_t* in, uint8_t len, uint8_t* out) {
    uint8_t i = 0;
    uint8_t o = 0;
    while (i < len) {
        uint8_t code = in[i];
        if (code == 0 || static_cast<uint16_t>(i) + code > len) return -1;
        i++;
        for (uint8_t k = 1; k < code; k++) {
            if (in[i] == 0) return -1;
            out[o++] = in[i++];
        }
        // A code < 0xFF ends a run with an implied zero, except at the very end of the frame.
        if (code != 0xFF && i < len) out[o++] = 0;
    }
    return o;
}
