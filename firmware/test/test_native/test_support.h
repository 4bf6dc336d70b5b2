// Fakes shared by the native tests: an EEPROM in RAM with a busy flag, a TX capture.
#ifndef TEST_SUPPORT_H
#define TEST_SUPPORT_H

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "app.h"
#include "enc.h"

#include "params.h"
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

// A GB54-1-like gimbal motor on a 12 V bus, voltage mode, resistance-dominated.
struct Motor {
    double theta = 0.3, omega = 0;
    double j = 2e-4, b = 1e-5, kt = 0.05, r = 10.0, vbus = 12.0;
    int pp = 7;
    double elec = 0;  // electrical angle at encoder zero, rad
    // noise_counts: added to the read angle before it is quantised (encoder noise).
    uint16_t word(double noise_counts = 0.0) const {
        double turns = theta / (2 * M_PI);
        long counts =
            static_cast<long>(floor((turns - floor(turns)) * 16384.0 + noise_counts)) & 0x3FFF;
        return enc_make_reply(static_cast<uint16_t>(counts), false);
    }
    void run(const uint16_t d[3], bool enabled, double dt) {
        const int sub = 20;
        double a = d[0] - 400.0, bb = d[1] - 400.0, c = d[2] - 400.0;
        double alpha = (2.0 / 3.0) * (a - 0.5 * (bb + c)) * vbus / 800.0;
        double beta = (bb - c) / sqrt(3.0) * vbus / 800.0;
        for (int i = 0; i < sub; i++) {
            double th_e = pp * theta + elec;
            double vq = enabled ? (-alpha * sin(th_e) + beta * cos(th_e)) : 0.0;
            double iq = enabled ? (vq - kt * omega) / r : 0.0;
            double tau = kt * iq - b * omega;
            omega += tau / j * dt / sub;
            theta += omega * dt / sub;
        }
    }
};

// Standard normal samples from mt19937 (fully specified) by Box-Muller, so that a seed gives the
// same sequence with any standard library (std::normal_distribution's algorithm is not fixed).
struct Gauss {
    std::mt19937 g;
    explicit Gauss(uint32_t seed) : g(seed) {}
    double next() {
        const double u1 = (static_cast<double>(g()) + 1.0) / 4294967297.0;  // (0, 1)
        const double u2 = static_cast<double>(g()) / 4294967296.0;
        return sqrt(-2.0 * log(u1)) * cos(2.0 * M_PI * u2);
    }
};

// The control step under a host whose control thread is alive (a control frame every tick), for
// tests that run longer than HEARTBEAT_MS allows (1000 ms at most) and are not about the heartbeat.
inline void app_step_alive(app_state* a, const uint16_t enc_words[APP_WHEELS]) {
    flt_host_alive(&a->flt);
    app_control_step(a, enc_words);
}

#endif  // TEST_SUPPORT_H
