#include "test_support.h"

uint8_t FakeEeprom::mem[4096];
int FakeEeprom::busy_polls = 0;
int FakeEeprom::busy_left = 0;
int FakeEeprom::writes = 0;
const prm_eeprom_if FakeEeprom::iface = {FakeEeprom::read, FakeEeprom::ready, FakeEeprom::write};

std::vector<RxFrame> TxCapture::frames;
bool TxCapture::full = false;
proto_rx TxCapture::rx;

bool TxCapture::tx(const uint8_t* data, uint8_t len) {
    if (full) return false;
    for (uint8_t i = 0; i < len; i++) {
        proto_frame f;
        if (proto_rx_push(&rx, data[i], &f) == PROTO_RX_FRAME) {
            frames.push_back({f.id, std::vector<uint8_t>(f.payload, f.payload + f.len)});
        }
    }
    return true;
}
