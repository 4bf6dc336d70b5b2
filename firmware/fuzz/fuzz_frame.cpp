// libFuzzer target: arbitrary bytes into the frame decoder and the whole dispatcher.
// Checks: no crash/UB (ASan, UBSan), every reply the device sends is itself a valid frame, and a
// frame built from the input decodes back to the same bytes.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "app.h"
#include "enc.h"
#include "proto.h"

namespace {

uint8_t g_ee[PRM_EEPROM_USED + 16];
uint8_t ee_read(uint16_t a) {
    return a < sizeof g_ee ? g_ee[a] : 0xFF;
}
bool ee_ready() {
    return true;
}
void ee_write(uint16_t a, uint8_t v) {
    if (a < sizeof g_ee) g_ee[a] = v;
}
const prm_eeprom_if g_iface = {ee_read, ee_ready, ee_write};

proto_rx g_check;
bool tx_check(const uint8_t* data, uint8_t len) {
    if (len == 0 || len > PROTO_MAX_WIRE || data[len - 1] != 0) abort();
    for (uint8_t i = 0; i < len; i++) {
        proto_frame f;
        proto_rx_result r = proto_rx_push(&g_check, data[i], &f);
        if (i + 1 < len && r != PROTO_RX_NONE) abort();
        if (i + 1 == len && r != PROTO_RX_FRAME) abort();
    }
    return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static app_state app;
    memset(g_ee, 0xFF, sizeof g_ee);
    proto_rx_init(&g_check);
    app_init(&app, &g_iface, tx_check, 0);
    const uint16_t words[4] = {enc_make_reply(1, false), enc_make_reply(2, true), 0xFFFF, 0};
    for (size_t i = 0; i < size; i++) {
        app_rx_byte(&app, data[i]);
        if ((i & 7) == 0) {
            app_control_step(&app, words);
            app_telemetry(&app, static_cast<uint32_t>(i));
            app_poll(&app);
        }
    }
    // Round trip: any payload up to the maximum survives build + receive unchanged.
    if (size >= 1) {
        uint8_t len = static_cast<uint8_t>((size - 1) % (PROTO_MAX_PAYLOAD + 1));
        uint8_t wire[PROTO_MAX_WIRE];
        uint8_t n = proto_build(data[0], data + 1, len, wire);
        proto_rx rx;
        proto_rx_init(&rx);
        proto_frame f;
        proto_rx_result r = PROTO_RX_NONE;
        for (uint8_t i = 0; i < n; i++) r = proto_rx_push(&rx, wire[i], &f);
        if (r == PROTO_RX_FRAME || r == PROTO_RX_UNKNOWN_ID || r == PROTO_RX_BAD_LENGTH) {
            if (f.id != data[0] || f.len != len || memcmp(f.payload, data + 1, len) != 0) abort();
        } else {
            abort();
        }
    }
    return 0;
}
