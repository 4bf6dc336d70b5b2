// Fakes shared by the native tests: an EEPROM in RAM with a busy flag, a TX capture.
#ifndef TEST_SUPPORT_H
#define TEST_SUPPORT_H

#include <cstdint>
#include <vector>

#include "prm.h"
#include "proto.h"

struct FakeEeprom {
    static uint8_t mem[4096];
    static int busy_polls;  // ready() is false for this many calls after each write
    static int busy_left;
    static int writes;
    static void erase() {
        for (auto& b : mem) b = 0xFF;
        busy_left = 0;
        writes = 0;
    }
    static uint8_t read(uint16_t a) { return mem[a]; }
    static bool ready() {
        if (busy_left > 0) {
            busy_left--;
            return false;
        }
        return true;
    }
    static void write(uint16_t a, uint8_t v) {
        mem[a] = v;
        writes++;
        busy_left = busy_polls;
    }
    static const prm_eeprom_if iface;
};

struct RxFrame {
    uint8_t id;
    std::vector<uint8_t> payload;
};

// Collects every frame the app sends, decoded with the same receiver the device uses.
struct TxCapture {
    static std::vector<RxFrame> frames;
    static bool full;  // simulate a full TX ring
    static proto_rx rx;
    static bool tx(const uint8_t* data, uint8_t len);
    static void reset() {
        frames.clear();
        full = false;
        proto_rx_init(&rx);
    }
};

#endif  // TEST_SUPPORT_H
