// Application: dispatcher replies, refused setpoints, fail-safe timing, corrupt-frame counters,
// telemetry rate, encoder faults, and the closed speed loop on a simulated gimbal motor.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "app.h"
#include "cobs.h"
#include "crc16.h"
#include "enc.h"
#include "app_step.h"
#include "test_support.h"

namespace {

using Bytes = std::vector<uint8_t>;

class AppTest : public ::testing::Test {
   protected:
    app_state app;
    void SetUp() override {
        FakeEeprom::erase();
        FakeEeprom::busy_polls = 0;
        TxCapture::reset();
        app_init(&app, &FakeEeprom::iface, TxCapture::tx, 0);
        // A blank EEPROM set PARAMS_DEFAULTED and left the offsets uncalibrated: tests start
        // clean (the tests of that rule set it up again).
        app.flt.faults = 0;
        app.uncal_mask = 0;
        TxCapture::frames.clear();
    }
    void send_wire(const Bytes& wire) {
        for (uint8_t b : wire) app_rx_byte(&app, b);
    }
    void send(uint8_t id, const Bytes& payload = {}) {
        uint8_t out[PROTO_MAX_WIRE];
        uint8_t n = proto_build(id, payload.data(), static_cast<uint8_t>(payload.size()), out);
        send_wire(Bytes(out, out + n));
    }
    static Bytes i32s(std::initializer_list<int32_t> v) {
        Bytes b;
        for (int32_t x : v) {
            uint8_t t[4];
            proto_put_i32(t, x);
            b.insert(b.end(), t, t + 4);
        }
        return b;
    }
    void set_param(uint8_t id, int32_t v) {
        Bytes p = {id};
        Bytes x = i32s({v});
        p.insert(p.end(), x.begin(), x.end());
        send(PROTO_ID_PARAM_SET, p);
    }
    void clear_faults(uint16_t mask = 0xFFFF) {
        uint8_t p[2];
        proto_put_u16(p, mask);
        send(PROTO_ID_CLEAR_FAULTS, Bytes(p, p + 2));
    }
    void step(int n = 1) {
        const uint16_t zero[4] = {enc_make_reply(0, false), enc_make_reply(0, false),
                                  enc_make_reply(0, false), enc_make_reply(0, false)};
        for (int i = 0; i < n; i++) app_control_step(&app, zero);
    }
    void step_alive(int n = 1) {
        const uint16_t zero[4] = {enc_make_reply(0, false), enc_make_reply(0, false),
                                  enc_make_reply(0, false), enc_make_reply(0, false)};
        for (int i = 0; i < n; i++) app_step_alive(&app, zero);
    }
    // Wheel 0 commanded to 50 rad/s (fast ramps, no heartbeat time-out) while its encoder turns
    // on its own at 49.9 rad/s, whatever the drive: a wheel that does not slow down.
    uint32_t free_angle = 0;
    void command_free_wheel0() {
        set_param(PRM_HEARTBEAT_MS, 1000);
        set_param(PRM_ACCEL_RAD_S2, 10000);
        set_param(PRM_DECEL_RAD_S2, 10000);
        send(PROTO_ID_SET_SPEEDS, i32s({50000, 0, 0, 0}));
    }
    void step_free_wheel0(bool bad_word = false) {
        free_angle += 130;  // counts per tick: 49.9 rad/s
        const uint16_t words[4] = {
            enc_make_reply(static_cast<uint16_t>(free_angle & 0x3FFF), bad_word),
            enc_make_reply(0, false), enc_make_reply(0, false), enc_make_reply(0, false)};
        app_step_alive(&app, words);
    }
    const RxFrame* last(uint8_t id) {
        for (auto it = TxCapture::frames.rbegin(); it != TxCapture::frames.rend(); ++it) {
            if (it->id == id) return &*it;
        }
        return nullptr;
    }
    int count(uint8_t id) {
        int n = 0;
        for (auto& f : TxCapture::frames) n += f.id == id;
        return n;
    }
    void expect_error(uint8_t req, uint8_t code, uint8_t detail) {
        const RxFrame* e = last(PROTO_ID_ERROR);
        ASSERT_NE(e, nullptr);
        EXPECT_EQ(e->payload[0], req);
        EXPECT_EQ(e->payload[1], code);
        EXPECT_EQ(e->payload[2], detail);
    }
};

TEST_F(AppTest, HelloReplyCarriesVersions) {
    send(PROTO_ID_HELLO);
    const RxFrame* h = last(PROTO_ID_HELLO_REPLY);
    ASSERT_NE(h, nullptr);
    EXPECT_EQ(h->payload[0], PROTO_VERSION);
    EXPECT_EQ(h->payload[3], 4);
    EXPECT_EQ(h->payload[4], PRM_COUNT);
    EXPECT_EQ(proto_get_u16(&h->payload[5]), 1000);
}

TEST_F(AppTest, SetpointAboveMaxRefusedWholeMessage) {
    set_param(PRM_MODE, 1);
    int32_t vmax = app.prm.v[PRM_SPEED_MAX_MRAD_S];
    send(PROTO_ID_SET_SPEEDS, i32s({1000, 2000, vmax + 1, 0}));
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_SETPOINT_ABOVE_MAX, 2);
    for (int i = 0; i < 4; i++) EXPECT_EQ(app.w[i].target_mrad_s, 0);
    send(PROTO_ID_SET_SPEEDS, i32s({-vmax - 1, 0, 0, 0}));
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_SETPOINT_ABOVE_MAX, 0);
    send(PROTO_ID_SET_SPEEDS, i32s({INT32_MIN, 0, 0, 0}));
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_SETPOINT_ABOVE_MAX, 0);
    int errors = count(PROTO_ID_ERROR);
    send(PROTO_ID_SET_SPEEDS, i32s({vmax, -vmax, 0, 1}));
    EXPECT_EQ(count(PROTO_ID_ERROR), errors);
    EXPECT_EQ(app.w[0].target_mrad_s, vmax);
    EXPECT_EQ(app.w[1].target_mrad_s, -vmax);
}

TEST_F(AppTest, HeartbeatLossAtConfiguredTimeThenRampToZero) {
    set_param(PRM_MODE, 1);
    set_param(PRM_HEARTBEAT_MS, 100);
    set_param(PRM_ACCEL_RAD_S2, 1000);
    set_param(PRM_DECEL_RAD_S2, 300);
    send(PROTO_ID_SET_SPEEDS, i32s({50000, -50000, 20000, 0}));
    step(99);  // 99 ms since the last frame: still alive
    EXPECT_EQ(app.flt.faults & PROTO_FAULT_HEARTBEAT_LOST, 0);
    EXPECT_EQ(app.w[0].sp_mrad_s, 50000);
    EXPECT_EQ(app.enable_mask, 0x7);
    step(1);  // 100 ms: fail-safe latches and the ramp down starts in this very tick
    EXPECT_NE(app.flt.faults & PROTO_FAULT_HEARTBEAT_LOST, 0);
    EXPECT_NE(app_status(&app) & PROTO_STATUS_FAILSAFE, 0);
    EXPECT_EQ(app.w[0].sp_mrad_s, 50000 - 300);
    EXPECT_EQ(app.w[1].sp_mrad_s, -50000 + 300);
    int ticks = 1;
    while (app.enable_mask && ticks < 1000) {
        step();
        ticks++;
    }
    // ceil(50000 / 300) = 167 ramp steps; the step of the next tick switches the outputs off (the
    // ramp runs after the step, app_setpoints_tick).
    EXPECT_EQ(ticks, 168);
    for (int i = 0; i < 4; i++) EXPECT_EQ(app.w[i].sp_mrad_s, 0);
    // Setpoints refused until the fault is cleared.
    send(PROTO_ID_SET_SPEEDS, i32s({1000, 0, 0, 0}));
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_FAULT_ACTIVE, 0);
    EXPECT_EQ(app.w[0].target_mrad_s, 0);
    clear_faults();
    EXPECT_EQ(last(PROTO_ID_ACK)->payload[0], PROTO_ID_CLEAR_FAULTS);
    send(PROTO_ID_SET_SPEEDS, i32s({1000, 0, 0, 0}));
    EXPECT_EQ(app.w[0].target_mrad_s, 1000);
}

// HEARTBEAT, SET_SPEEDS and STOP_ALL each restart the heartbeat count.
TEST_F(AppTest, ControlFramesKeepTheWheelsRunning) {
    set_param(PRM_MODE, 1);
    set_param(PRM_HEARTBEAT_MS, 100);
    send(PROTO_ID_SET_SPEEDS, i32s({10000, 0, 0, 0}));
    for (int i = 0; i < 50; i++) {
        step(99);
        if (i % 2) {
            send(PROTO_ID_HEARTBEAT);
        } else {
            send(PROTO_ID_SET_SPEEDS, i32s({10000, 0, 0, 0}));
        }
    }
    EXPECT_EQ(app.flt.faults, 0);
    EXPECT_EQ(app.w[0].sp_mrad_s, 10000);
    send(PROTO_ID_STOP_ALL);
    step(99);
    EXPECT_EQ(app.flt.faults, 0);
}

// A host whose control thread died while its poller lives: queries keep nothing running.
TEST_F(AppTest, QueriesDoNotFeedTheHeartbeat) {
    set_param(PRM_MODE, 1);
    set_param(PRM_HEARTBEAT_MS, 100);
    send(PROTO_ID_SET_SPEEDS, i32s({10000, 0, 0, 0}));
    for (int i = 0; i < 10; i++) {
        step(10);
        send(PROTO_ID_GET_STATS);
        send(PROTO_ID_HELLO);
        send(PROTO_ID_PARAM_GET, {PRM_KP});
        send(PROTO_ID_TELEMETRY, Bytes(PROTO_LEN_TELEMETRY, 1));  // device-to-host id
    }
    EXPECT_NE(app.flt.faults & PROTO_FAULT_HEARTBEAT_LOST, 0);
    EXPECT_EQ(app.w[0].target_mrad_s, 0);
}

// Open loop is supervised: its time limit stops it (as the heartbeat does, test above), its
// drive is capped at DRIVE_MAX, and it is never restored at boot.
TEST_F(AppTest, OpenLoopStopsAtItsTimeLimit) {
    set_param(PRM_MODE, 1);
    set_param(PRM_DECEL_RAD_S2, 1000);
    send(PROTO_ID_SET_SPEEDS, i32s({10000, 0, 0, -5000}));
    step_alive(APP_OPEN_LOOP_MS - 1);
    EXPECT_EQ(app.flt.faults, 0);
    EXPECT_EQ(app.enable_mask, 0x9);
    step_alive(1);  // the ramp down starts in this tick
    EXPECT_NE(app.flt.faults & PROTO_FAULT_OPEN_LOOP_LIMIT, 0);
    EXPECT_EQ(app.w[0].sp_mrad_s, 9000);
    step_alive(11);  // 10 ramp steps, the next step switches the outputs off
    EXPECT_EQ(app.enable_mask, 0);
    send(PROTO_ID_SET_SPEEDS, i32s({10000, 0, 0, 0}));
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_FAULT_ACTIVE, 0);
    clear_faults(PROTO_FAULT_OPEN_LOOP_LIMIT);
    send(PROTO_ID_SET_SPEEDS, i32s({10000, 0, 0, 0}));
    EXPECT_EQ(app.w[0].target_mrad_s, 10000);
    step_alive(APP_OPEN_LOOP_MS - 1);  // the count began again at the stop
    EXPECT_EQ(app.flt.faults, 0);
}

TEST_F(AppTest, OpenLoopDriveCappedAtDriveMax) {
    set_param(PRM_MODE, 1);
    set_param(PRM_OPEN_LOOP_DRIVE_Q15, 16385);
    expect_error(PROTO_ID_PARAM_SET, PROTO_ERR_PARAM_OUT_OF_RANGE, PRM_OPEN_LOOP_DRIVE_Q15);
    set_param(PRM_DRIVE_MAX_Q15, 4000);
    send(PROTO_ID_SET_SPEEDS, i32s({10000, 0, 0, 0}));
    step(2);
    EXPECT_EQ(app.w[0].drive_q15, 4000);  // OPEN_LOOP_DRIVE 6000 capped
}

TEST_F(AppTest, OpenLoopIsNeverRestoredAtBoot) {
    set_param(PRM_MODE, 1);
    send(PROTO_ID_PARAM_SAVE);
    for (int i = 0; i < 1000 && !last(PROTO_ID_ACK); i++) {
        app_poll(&app);
        app_reply_work(&app);
    }
    ASSERT_NE(last(PROTO_ID_ACK), nullptr);
    app_state booted;
    app_init(&booted, &FakeEeprom::iface, TxCapture::tx, 0);
    EXPECT_EQ(booted.prm.v[PRM_MODE], 0);
    EXPECT_EQ(booted.ctl.closed, 1);
    EXPECT_EQ(booted.flt.faults & PROTO_FAULT_PARAMS_DEFAULTED, 0);  // the image itself loaded
}

TEST_F(AppTest, StopAllRampsWithDecelAndAcks) {
    set_param(PRM_MODE, 1);
    set_param(PRM_DECEL_RAD_S2, 500);
    send(PROTO_ID_SET_SPEEDS, i32s({10000, 10000, 10000, 10000}));
    step(200);
    send(PROTO_ID_STOP_ALL);
    EXPECT_EQ(last(PROTO_ID_ACK)->payload[0], PROTO_ID_STOP_ALL);
    step(1);
    EXPECT_EQ(app.w[3].sp_mrad_s, 9500);
    step(19);
    EXPECT_EQ(app.w[3].sp_mrad_s, 0);
    EXPECT_EQ(app.enable_mask, 0xF);  // the step works on the setpoints of the tick before
    step(1);
    EXPECT_EQ(app.enable_mask, 0);
}

TEST_F(AppTest, CorruptFramesCountedDroppedAndReported) {
    Bytes bad_crc = {0x04, 0x05, 0x01, 0x02, 0x00};  // PARAM_GET with a wrong CRC
    send_wire(bad_crc);
    send_wire({0x02, 0x05, 0x00});  // short: id only
    send_wire(Bytes(120, 0x33));    // oversize...
    send_wire({0x00});              // ...ends here
    send_wire({0x07, 0x01, 0x00});  // bad COBS: code past the end
    Bytes raw = {0x55, 1};          // unknown id, good CRC
    uint16_t c = crc16_ccitt(raw.data(), 2);
    raw.push_back(static_cast<uint8_t>(c));
    raw.push_back(static_cast<uint8_t>(c >> 8));
    uint8_t enc[16];
    uint8_t n = cobs_encode(raw.data(), 4, enc);
    Bytes w(enc, enc + n);
    w.push_back(0);
    send_wire(w);
    expect_error(0x55, PROTO_ERR_UNKNOWN_MESSAGE, 0x55);
    send(PROTO_ID_SET_SPEEDS, {1, 2, 3});  // wrong length
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_BAD_LENGTH, 3);
    send(PROTO_ID_TELEMETRY, Bytes(PROTO_LEN_TELEMETRY, 1));  // device-to-host id
    expect_error(PROTO_ID_TELEMETRY, PROTO_ERR_UNKNOWN_MESSAGE, PROTO_ID_TELEMETRY);
    send(PROTO_ID_STATS, {1, 2, 3});  // device-to-host id with another length: the same
    expect_error(PROTO_ID_STATS, PROTO_ERR_UNKNOWN_MESSAGE, PROTO_ID_STATS);
    send(PROTO_ID_GET_STATS);
    const RxFrame* s = last(PROTO_ID_STATS);
    ASSERT_NE(s, nullptr);
    const uint16_t want[] = {1, 1, 1, 1, 3, 1};  // crc short oversize cobs unknown length
    for (int i = 0; i < 6; i++) EXPECT_EQ(proto_get_u16(&s->payload[2 * i]), want[i]) << i;
    for (int i = 0; i < 4; i++) EXPECT_EQ(app.w[i].target_mrad_s, 0);
}

TEST_F(AppTest, CorruptFramesDoNotFeedTheHeartbeat) {
    set_param(PRM_HEARTBEAT_MS, 50);
    for (int i = 0; i < 50; i++) {
        send_wire({0x04, 0x05, 0x01, 0x02, 0x00});
        step();
    }
    EXPECT_NE(app.flt.faults & PROTO_FAULT_HEARTBEAT_LOST, 0);
}

// No value of a fail-safe parameter disarms its fail-safe (params.def, docs/hardware.md): each
// value beyond the bound is refused and the held value stays; the bound itself is accepted.
TEST_F(AppTest, DisarmingParamSetsRefused) {
    struct Case {
        uint8_t id;
        int32_t bound, beyond, far;
    };
    const Case cases[] = {
        {PRM_HEARTBEAT_MS, 1000, 1001, 60000},
        {PRM_DECEL_RAD_S2, 50, 49, 1},
        {PRM_STALL_SPEED_MRAD_S, 1000, 999, 0},
        {PRM_MOTION_FAULT_MS, 200, 201, 5000},
        {PRM_RUNAWAY_MARGIN_MRAD_S, 50000, 50001, 400000},
    };
    for (const Case& c : cases) {
        const int32_t held = app.prm.v[c.id];
        for (int32_t v : {c.beyond, c.far}) {
            set_param(c.id, v);
            expect_error(PROTO_ID_PARAM_SET, PROTO_ERR_PARAM_OUT_OF_RANGE, c.id);
            EXPECT_EQ(app.prm.v[c.id], held) << int(c.id) << " " << v;
        }
        set_param(c.id, c.bound);
        EXPECT_EQ(proto_get_i32(&last(PROTO_ID_PARAM_VALUE)->payload[1]), c.bound) << int(c.id);
    }
}

// An EEPROM image with a good CRC but a disarming value (written by hand, or by firmware with
// wider ranges) is invalid: the boot loads the defaults and reports PARAMS_DEFAULTED.
TEST_F(AppTest, EepromImageWithADisarmingValueRejectedAtBoot) {
    for (uint8_t id : {PRM_HEARTBEAT_MS, PRM_STALL_SPEED_MRAD_S}) {
        prm_store s;
        prm_defaults(&s);
        s.v[PRM_KP] = 77;
        s.v[id] = id == PRM_HEARTBEAT_MS ? 60000 : 0;  // past prm_set
        uint8_t img[PRM_IMAGE_SIZE];
        prm_image_build(&s, 1, img);
        FakeEeprom::erase();
        for (int i = 0; i < PRM_IMAGE_SIZE; i++) FakeEeprom::mem[PRM_SLOT_ADDR(0) + i] = img[i];
        app_state booted;
        app_init(&booted, &FakeEeprom::iface, TxCapture::tx, 0);
        EXPECT_NE(booted.flt.faults & PROTO_FAULT_PARAMS_DEFAULTED, 0) << int(id);
        EXPECT_EQ(booted.prm.v[id], prm_default(id));
        EXPECT_EQ(booted.prm.v[PRM_KP], prm_default(PRM_KP));
        s.v[id] = prm_default(id);  // the same image in range loads
        prm_image_build(&s, 1, img);
        for (int i = 0; i < PRM_IMAGE_SIZE; i++) FakeEeprom::mem[PRM_SLOT_ADDR(0) + i] = img[i];
        app_init(&booted, &FakeEeprom::iface, TxCapture::tx, 0);
        EXPECT_EQ(booted.flt.faults & PROTO_FAULT_PARAMS_DEFAULTED, 0);
        EXPECT_EQ(booted.prm.v[PRM_KP], 77);
    }
}

TEST_F(AppTest, ParamGetSetErrorsAndBusy) {
    send(PROTO_ID_PARAM_GET, {PRM_POLE_PAIRS});
    EXPECT_EQ(proto_get_i32(&last(PROTO_ID_PARAM_VALUE)->payload[1]), 7);
    send(PROTO_ID_PARAM_GET, {200});
    expect_error(PROTO_ID_PARAM_GET, PROTO_ERR_UNKNOWN_PARAM, 200);
    set_param(PRM_KP, -1);
    expect_error(PROTO_ID_PARAM_SET, PROTO_ERR_PARAM_OUT_OF_RANGE, PRM_KP);
    set_param(PRM_COUNT, 1);
    expect_error(PROTO_ID_PARAM_SET, PROTO_ERR_UNKNOWN_PARAM, PRM_COUNT);
    set_param(PRM_MODE, 1);
    send(PROTO_ID_SET_SPEEDS, i32s({5000, 0, 0, 0}));
    step(10);
    set_param(PRM_MODE, 0);  // structural change while running
    expect_error(PROTO_ID_PARAM_SET, PROTO_ERR_BUSY, PRM_MODE);
    EXPECT_EQ(app.prm.v[PRM_MODE], 1);
    set_param(PRM_KP, 300);  // gains may change while running
    EXPECT_EQ(proto_get_i32(&last(PROTO_ID_PARAM_VALUE)->payload[1]), 300);
}

TEST_F(AppTest, SaveAcksWhenWrittenAndSurvivesReboot) {
    FakeEeprom::busy_polls = 2;
    set_param(PRM_HEARTBEAT_MS, 777);
    send(PROTO_ID_PARAM_SAVE);
    EXPECT_EQ(count(PROTO_ID_ACK), 0);
    EXPECT_NE(app_status(&app) & PROTO_STATUS_SAVING, 0);
    send(PROTO_ID_PARAM_SAVE);
    expect_error(PROTO_ID_PARAM_SAVE, PROTO_ERR_BUSY, 0);
    for (int i = 0; i < 2000 && count(PROTO_ID_ACK) == 0; i++) {
        app_poll(&app);
        app_reply_work(&app);
    }
    ASSERT_EQ(count(PROTO_ID_ACK), 1);
    EXPECT_EQ(last(PROTO_ID_ACK)->payload[0], PROTO_ID_PARAM_SAVE);
    app_state again;
    app_init(&again, &FakeEeprom::iface, TxCapture::tx, 0);
    EXPECT_EQ(again.prm.v[PRM_HEARTBEAT_MS], 777);
    EXPECT_EQ(again.flt.faults & PROTO_FAULT_PARAMS_DEFAULTED, 0);
}

TEST_F(AppTest, BlankEepromReportsDefaults) {
    FakeEeprom::erase();
    app_state fresh;
    app_init(&fresh, &FakeEeprom::iface, TxCapture::tx, PROTO_FAULT_WATCHDOG_RESET);
    EXPECT_NE(fresh.flt.faults & PROTO_FAULT_PARAMS_DEFAULTED, 0);
    EXPECT_NE(fresh.flt.faults & PROTO_FAULT_WATCHDOG_RESET, 0);
}

TEST_F(AppTest, TelemetryRateSequenceAndDrops) {
    set_param(PRM_TELEMETRY_DIV, 2);
    TxCapture::frames.clear();
    for (uint32_t t = 0; t < 1000; t++) {
        step();
        send(PROTO_ID_HEARTBEAT);
        app_telemetry(&app, t * 1000);
    }
    EXPECT_EQ(count(PROTO_ID_TELEMETRY), 500);  // 500 Hz at the 1 kHz tick
    const RxFrame* t = last(PROTO_ID_TELEMETRY);
    EXPECT_EQ(proto_get_u16(&t->payload[4]), 499);
    EXPECT_EQ(proto_get_u32(&t->payload[0]), 999000u);
    TxCapture::full = true;
    step();
    app_telemetry(&app, 0);
    step();
    app_telemetry(&app, 0);
    EXPECT_EQ(app.cnt.tx_dropped, 1);
    TxCapture::full = false;
    step();
    app_telemetry(&app, 0);
    step();
    app_telemetry(&app, 0);
    EXPECT_EQ(proto_get_u16(&last(PROTO_ID_TELEMETRY)->payload[4]), 501);  // gap shows the drop
}

TEST_F(AppTest, EncoderFaultLatchesDisablesWheelAndBlocksSetpoints) {
    set_param(PRM_ENC_FAULT_LIMIT, 3);
    send(PROTO_ID_SET_SPEEDS, i32s({5000, 5000, 0, 0}));
    uint16_t words[4] = {enc_make_reply(0, false), enc_make_reply(0, true),
                         enc_make_reply(0, false), enc_make_reply(0, false)};
    app_control_step(&app, words);
    app_control_step(&app, words);
    EXPECT_EQ(app.flt.faults & PROTO_FAULT_ENCODER_M1, 0);
    words[1] = static_cast<uint16_t>(enc_make_reply(5, false) ^ 1);  // parity error
    app_control_step(&app, words);
    EXPECT_NE(app.flt.faults & PROTO_FAULT_ENCODER_M1, 0);
    EXPECT_EQ(app.enc_clear, 0x2);  // CLEAR ERROR FLAG after a bad word, parity ones too
    EXPECT_EQ(app.enable_mask & 0x2, 0);
    EXPECT_NE(app.enable_mask & 0x1, 0);
    send(PROTO_ID_SET_SPEEDS, i32s({1000, 0, 0, 0}));
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_FAULT_ACTIVE, 0);
}

// An AS5048A's error flag as on the chip: once set it stays in every reply until a CLEAR ERROR
// FLAG command is read (the board sends it after a step whose enc_clear bit is set).
struct LatchingSensor {
    bool flag = false;
    bool cause = false;  // the condition that sets the flag (present while true)
    uint16_t word(uint16_t angle) {
        if (cause) flag = true;
        return enc_make_reply(angle, flag);
    }
    void after_step(bool clear_sent) {
        if (clear_sent) flag = false;  // reading the error register clears it
    }
};

TEST_F(AppTest, TransientErrorFlagIsClearedAndCostsOneSample) {
    set_param(PRM_HEARTBEAT_MS, 1000);
    EXPECT_EQ(app.prm.v[PRM_ENC_FAULT_LIMIT], 5);
    send(PROTO_ID_SET_SPEEDS, i32s({5000, 0, 0, 0}));
    LatchingSensor chip;
    uint16_t angle = 0;
    auto tick = [&](int n) {
        for (int k = 0; k < n; k++) {
            angle = static_cast<uint16_t>((angle + 3) & 0x3FFF);
            // Wheel 0 runs (its word turns: a word stuck at 0 while driven latches ENC_STUCK).
            uint16_t words[4] = {enc_make_reply(angle, false), chip.word(angle),
                                 enc_make_reply(0, false), enc_make_reply(0, false)};
            app_step_alive(&app, words);
            chip.after_step((app.enc_clear >> 1) & 1);
        }
    };
    tick(10);
    EXPECT_EQ(app.enc_clear, 0);
    for (int glitch = 0; glitch < 50; glitch++) {  // 50 single glitches, each one clears
        chip.flag = true;
        tick(1);
        EXPECT_EQ(app.enc_clear, 0x2);
        tick(1);
        EXPECT_FALSE(chip.flag);
        EXPECT_EQ(app.flt.enc_bad[1], 0);
        tick(3);
    }
    chip.cause = true;  // a flag that lasts ENC_FAULT_LIMIT - 1 replies still recovers
    tick(4);
    chip.cause = false;
    tick(2);
    EXPECT_EQ(app.flt.faults, 0);
    EXPECT_EQ(app.enable_mask, 0x1);
    EXPECT_EQ(app.enc_clear, 0);
}

TEST_F(AppTest, PersistentErrorFlagFaultsAfterTheLimitThenRecoversAfterClear) {
    set_param(PRM_HEARTBEAT_MS, 1000);
    set_param(PRM_ENC_FAULT_LIMIT, 4);
    send(PROTO_ID_SET_SPEEDS, i32s({0, 5000, 0, 0}));
    LatchingSensor chip;
    auto tick = [&]() {
        uint16_t words[4] = {enc_make_reply(0, false), chip.word(100), enc_make_reply(0, false),
                             enc_make_reply(0, false)};
        app_step_alive(&app, words);
        chip.after_step((app.enc_clear >> 1) & 1);
    };
    tick();
    EXPECT_EQ(app.enable_mask, 0x2);
    chip.cause = true;
    for (int k = 0; k < 3; k++) {
        tick();
        EXPECT_EQ(app.flt.faults & PROTO_FAULT_ENCODER_M1, 0) << k;
        EXPECT_EQ(app.enc_clear, 0x2);
    }
    tick();  // the 4th consecutive bad reply
    EXPECT_NE(app.flt.faults & PROTO_FAULT_ENCODER_M1, 0);
    EXPECT_EQ(app.enable_mask, 0);
    EXPECT_EQ(app.enc_clear, 0x2);  // still clearing while faulted
    chip.cause = false;             // the cause goes away: the next clear empties the flag
    tick();
    tick();
    EXPECT_FALSE(chip.flag);
    EXPECT_EQ(app.enc_clear, 0);
    clear_faults();
    send(PROTO_ID_SET_SPEEDS, i32s({0, 5000, 0, 0}));
    tick();
    EXPECT_EQ(app.flt.faults, 0);
    EXPECT_EQ(app.enable_mask, 0x2);
}

TEST_F(AppTest, OverrunAndRxOverflowSetFaults) {
    app_note_overrun(&app, 3);
    app_note_rx_overflow(&app, 0);
    EXPECT_EQ(app.cnt.tick_overruns, 3);
    EXPECT_NE(app.flt.faults & PROTO_FAULT_TICK_OVERRUN, 0);
    EXPECT_NE(app.flt.faults & PROTO_FAULT_RX_OVERFLOW, 0);
    EXPECT_FALSE(flt_blocks_setpoints(&app.flt));  // informational faults do not block
}

TEST_F(AppTest, OpenLoopAdvancesPhaseAtCommandedSpeed) {
    set_param(PRM_MODE, 1);
    set_param(PRM_HEARTBEAT_MS, 1000);
    set_param(PRM_ACCEL_RAD_S2, 10000);
    send(PROTO_ID_SET_SPEEDS, i32s({74870, 0, 0, -74870}));
    step_alive(100);  // ramp done after 8 ticks
    uint32_t p0 = app.w[0].ol_phase;
    step_alive(1000);
    // 1 s at 74.87 rad/s and 7 pole pairs: 7 * 74.87 / (2 pi) = 83.41 electrical turns.
    double turns = 7 * 74.870 / (2 * M_PI);
    double frac = turns - floor(turns);
    double got = static_cast<uint32_t>(app.w[0].ol_phase - p0) / 4294967296.0;
    EXPECT_NEAR(got, frac, 1e-3);
    EXPECT_EQ(app_speed_mrad_s(&app, 0), 74870);
    EXPECT_EQ(app.w[0].drive_q15, app.prm.v[PRM_OPEN_LOOP_DRIVE_Q15]);
    EXPECT_EQ(app.w[3].drive_q15, -app.prm.v[PRM_OPEN_LOOP_DRIVE_Q15]);
    EXPECT_NE(app_status(&app) & PROTO_STATUS_OPEN_LOOP, 0);
}

TEST_F(AppTest, ClosedLoopHoldsSpeedOnSimulatedMotor) {
    set_param(PRM_DRIVE_MAX_Q15, 32767);
    set_param(PRM_HEARTBEAT_MS, 1000);
    Motor m[4];
    const int32_t sp[4] = {74870, -74870, 20000, 0};
    send(PROTO_ID_SET_SPEEDS, i32s({sp[0], sp[1], sp[2], sp[3]}));
    double mean[4] = {0, 0, 0, 0};
    for (int t = 0; t < 4000; t++) {
        uint16_t words[4];
        for (int i = 0; i < 4; i++) words[i] = m[i].word();
        app_step_alive(&app, words);
        for (int i = 0; i < 4; i++) {
            m[i].run(app.pwm[i], (app.enable_mask >> i) & 1, 1e-3);
            if (t >= 3000) mean[i] += m[i].omega / 1000.0;
        }
    }
    for (int i = 0; i < 3; i++) {
        EXPECT_NEAR(mean[i], sp[i] / 1000.0, 0.005 * fabs(sp[i] / 1000.0)) << "wheel " << i;
        EXPECT_NEAR(app_speed_mrad_s(&app, static_cast<uint8_t>(i)), sp[i], 1500) << "wheel " << i;
    }
    EXPECT_NEAR(m[3].omega, 0.0, 1e-9);
    EXPECT_EQ(app.flt.faults, 0);
}

// Overruns of the main loop: every third step comes two ticks after the one before (the motor
// turned for 2 ms on the held PWM). The estimator divides those deltas by 2, so the loop still
// holds the wheel at its setpoint and telemetry reports the true speed (before, telemetry read high
// and the wheel ran slow).
TEST_F(AppTest, MissedTicksKeepSpeedEstimateAndLoopRight) {
    set_param(PRM_DRIVE_MAX_Q15, 32767);
    set_param(PRM_HEARTBEAT_MS, 1000);
    Motor m[4];
    const int32_t sp[4] = {74870, -74870, 20000, 0};
    send(PROTO_ID_SET_SPEEDS, i32s({sp[0], sp[1], sp[2], sp[3]}));
    double mean[4] = {0, 0, 0, 0};
    int32_t reported_max_err = 0;
    int n = 0;
    for (int t = 0; t < 6000; t++) {
        if (t % 3 == 2) {  // a tick without a step: the motor turns on with the PWM held
            for (int i = 0; i < 4; i++) m[i].run(app.pwm[i], (app.enable_mask >> i) & 1, 1e-3);
            app_note_overrun(&app, 1);
        }
        uint16_t words[4];
        for (int i = 0; i < 4; i++) words[i] = m[i].word();
        app_step_alive(&app, words);
        for (int i = 0; i < 4; i++) {
            m[i].run(app.pwm[i], (app.enable_mask >> i) & 1, 1e-3);
            if (t >= 4500) mean[i] += m[i].omega;
        }
        if (t >= 4500) {
            n++;
            for (int i = 0; i < 3; i++) {
                int32_t e = app_speed_mrad_s(&app, static_cast<uint8_t>(i)) -
                            static_cast<int32_t>(lround(m[i].omega * 1000));
                if (abs(e) > reported_max_err) reported_max_err = abs(e);
            }
        }
    }
    for (int i = 0; i < 3; i++) {
        mean[i] /= n;
        EXPECT_NEAR(mean[i], sp[i] / 1000.0, 0.005 * fabs(sp[i] / 1000.0)) << "wheel " << i;
        EXPECT_NEAR(app_speed_mrad_s(&app, static_cast<uint8_t>(i)), sp[i], 0.005 * fabs(sp[i]))
            << "wheel " << i;
    }
    // Reported against true speed at every step: within the speed ripple of the loop.
    EXPECT_LT(reported_max_err, 1500);
    EXPECT_NEAR(m[3].omega, 0.0, 1e-9);
    EXPECT_EQ(app.cnt.tick_overruns, 2000);
    EXPECT_EQ(app.flt.faults, PROTO_FAULT_TICK_OVERRUN);
}

// Fail-safe in closed loop at the default DECEL (200 rad/s^2, faster than this motor brakes):
// the motor lags the ramp, so the loop brakes on after the setpoint reached 0 and disables the
// outputs only once the encoder shows the wheel below APP_STOP_Q8; going off when the setpoint
// reached 0 would leave the wheels coasting from the lag.
TEST_F(AppTest, FailSafeBrakesUntilTheWheelHasStopped) {
    set_param(PRM_DRIVE_MAX_Q15, 32767);
    set_param(PRM_HEARTBEAT_MS, 100);
    Motor m[4];
    const int32_t sp[4] = {74870, -74870, 20000, 0};
    send(PROTO_ID_SET_SPEEDS, i32s({sp[0], sp[1], sp[2], sp[3]}));
    int t_failsafe = -1, t_sp0[4] = {-1, -1, -1, -1}, t_off[4] = {-1, -1, -1, -1};
    double omega_off[4] = {0, 0, 0, 0};
    for (int t = 0; t < 8000; t++) {
        if (t < 4000 && t % 50 == 0) send(PROTO_ID_HEARTBEAT);  // then the host goes silent
        uint16_t words[4];
        for (int i = 0; i < 4; i++) words[i] = m[i].word();
        const uint8_t was = app.enable_mask;
        app_control_step(&app, words);
        if (t_failsafe < 0 && (app.flt.faults & PROTO_FAULT_HEARTBEAT_LOST)) t_failsafe = t;
        for (int i = 0; i < 4; i++) {
            if (t_failsafe >= 0 && t_sp0[i] < 0 && app.w[i].sp_mrad_s == 0) t_sp0[i] = t;
            if (((was & ~app.enable_mask) >> i) & 1) {
                t_off[i] = t;
                omega_off[i] = m[i].omega;
            }
            m[i].run(app.pwm[i], (app.enable_mask >> i) & 1, 1e-3);
        }
    }
    ASSERT_GT(t_failsafe, 4000);
    const double stop_rad_s = APP_STOP_Q8 * 1.4980e-3;  // q8 -> rad/s
    for (int i = 0; i < 3; i++) {
        ASSERT_GE(t_off[i], 0) << "wheel " << i;
        EXPECT_GT(t_off[i], t_sp0[i]) << "wheel " << i;  // braked on after the ramp ended
        EXPECT_LT(t_off[i] - t_sp0[i], static_cast<int>(APP_STOP_TICKS)) << "wheel " << i;
        // Off when stopped: below the threshold plus the filter's lag of a few ticks of braking.
        EXPECT_LT(fabs(omega_off[i]), 2 * stop_rad_s) << "wheel " << i;
        EXPECT_LT(fabs(m[i].omega), 2 * stop_rad_s) << "wheel " << i;
    }
    EXPECT_EQ(t_off[3], -1);  // never enabled
    EXPECT_EQ(app.enable_mask, 0);
}

// STOP_ALL from +-715 rpm at the default DECEL (the motor lags the ramp): braking ends when the
// encoder shows the wheel stopped, not when the lagging filtered estimate does, so no wheel turns
// backwards: the true speed never passes 0.5 rad/s the wrong way, and it is released within
// 0.8 rad/s of zero (the window's mean below 1.3 counts a tick, its change resolved to a count:
// (5.2 + 1) / 4 counts a tick, 0.59 rad/s).
TEST_F(AppTest, StopAllEndsBrakingWhenTheEncoderShowsStoppedNeverReversing) {
    set_param(PRM_DRIVE_MAX_Q15, 32767);
    set_param(PRM_HEARTBEAT_MS, 1000);
    Motor m[4];
    const int32_t sp[4] = {74870, -74870, 20000, -5000};
    send(PROTO_ID_SET_SPEEDS, i32s({sp[0], sp[1], sp[2], sp[3]}));
    int t_off[4] = {-1, -1, -1, -1}, t_sp0[4] = {-1, -1, -1, -1};
    double omega_off[4] = {0, 0, 0, 0}, wrong_way[4] = {0, 0, 0, 0};
    for (int t = 0; t < 7000; t++) {
        if (t == 4000) {
            for (int i = 0; i < 4; i++) ASSERT_NEAR(m[i].omega, sp[i] * 1e-3, 0.05 * 78.4);
            send(PROTO_ID_STOP_ALL);
        }
        uint16_t words[4];
        for (int i = 0; i < 4; i++) words[i] = m[i].word();
        const uint8_t was = app.enable_mask;
        app_step_alive(&app, words);
        for (int i = 0; i < 4; i++) {
            if (((was & ~app.enable_mask) >> i) & 1) {
                t_off[i] = t;
                omega_off[i] = m[i].omega;
            }
            m[i].run(app.pwm[i], (app.enable_mask >> i) & 1, 1e-3);
            if (t >= 4000 && t_sp0[i] < 0 && app.w[i].sp_mrad_s == 0) t_sp0[i] = t;
            if (t >= 4000) {
                const double back = sp[i] > 0 ? -m[i].omega : m[i].omega;
                if (back > wrong_way[i]) wrong_way[i] = back;
            }
        }
    }
    for (int i = 0; i < 4; i++) {
        ASSERT_GT(t_off[i], 4000) << "wheel " << i;
        EXPECT_LT(t_off[i] - t_sp0[i], static_cast<int>(APP_STOP_TICKS)) << "wheel " << i;
        EXPECT_LT(fabs(omega_off[i]), 0.8) << "wheel " << i;
        EXPECT_LT(wrong_way[i], 0.5) << "wheel " << i;  // never reversed
        EXPECT_LT(fabs(m[i].omega), 0.8) << "wheel " << i;
    }
    EXPECT_EQ(app.enable_mask, 0);
}

// The same stop on an encoder with the AS5048A's noise at rest (2 counts rms on every read), 25
// times over. The release is judged on the angle change over APP_STOP_WINDOW ticks (app.h), whose
// noise is 2.83 counts rms: at 4 sigma a wheel goes at a mean speed over the window of at most
// (4 * 1.3 + 4 * 2.83) / 4 = 4.13 counts a tick (1.58 rad/s; the present speed of a braked wheel
// is lower), and, braking at up to 275 rad/s^2 (the window's mean 1.43 counts a tick ahead of the
// present speed), it has not turned backwards faster than (4 * 1.3 - 4 * 2.83) / 4 - 1.43 =
// -2.96 counts a tick (1.13 rad/s). One tick's change against 1.3 counts would allow
// 1.3 + 4 * 2.83 = 12.6 counts a tick at 4 sigma (4.8 rad/s).
TEST_F(AppTest, StopAllUnderEncoderNoiseReleasesWithinTheWindowsBounds) {
    set_param(PRM_DRIVE_MAX_Q15, 32767);
    set_param(PRM_HEARTBEAT_MS, 1000);
    const double count_rad_s = 2 * M_PI / 16384.0 * 1000.0;  // one count a tick
    const double release_max = 4.13 * count_rad_s, backwards_max = 2.96 * count_rad_s;
    const int32_t sp[4] = {74870, -74870, 74870, -74870};
    Gauss noise(7);
    Motor m[4];
    double fastest = 0, wrong_way = 0;
    for (int stop = 0; stop < 25; stop++) {
        send(PROTO_ID_SET_SPEEDS, i32s({sp[0], sp[1], sp[2], sp[3]}));
        int t_off[4] = {-1, -1, -1, -1}, t_sp0[4] = {-1, -1, -1, -1};
        for (int t = 0; t < 3500; t++) {
            if (t == 2000) send(PROTO_ID_STOP_ALL);
            uint16_t words[4];
            for (int i = 0; i < 4; i++) words[i] = m[i].word(2.0 * noise.next());
            const uint8_t was = app.enable_mask;
            app_step_alive(&app, words);
            for (int i = 0; i < 4; i++) {
                if (((was & ~app.enable_mask) >> i) & 1) {
                    t_off[i] = t;
                    fastest = std::max(fastest, fabs(m[i].omega));
                }
                m[i].run(app.pwm[i], (app.enable_mask >> i) & 1, 1e-3);
                if (t < 2000) continue;
                if (t_sp0[i] < 0 && app.w[i].sp_mrad_s == 0) t_sp0[i] = t;
                wrong_way = std::max(wrong_way, sp[i] > 0 ? -m[i].omega : m[i].omega);
            }
        }
        ASSERT_EQ(app.flt.faults, 0) << "stop " << stop;
        for (int i = 0; i < 4; i++) {
            ASSERT_GT(t_off[i], t_sp0[i]) << "stop " << stop << " wheel " << i;
            EXPECT_LT(t_off[i] - t_sp0[i], static_cast<int>(APP_STOP_TICKS)) << "wheel " << i;
        }
    }
    EXPECT_LT(fastest, release_max);
    EXPECT_LT(wrong_way, backwards_max);
}

// A bad encoder word while braking is not taken for a stopped wheel: the tick is not judged.
TEST_F(AppTest, BadWordWhileBrakingDoesNotEndTheStop) {
    command_free_wheel0();
    for (int t = 0; t < 300; t++) step_free_wheel0();
    send(PROTO_ID_STOP_ALL);
    for (int t = 0; t < 20; t++) step_free_wheel0();
    ASSERT_EQ(app.enable_mask, 0x1);
    step_free_wheel0(true);  // the angle held: a zero change if it were judged
    EXPECT_EQ(app.enable_mask, 0x1);
    step_free_wheel0();  // the first good word after it only takes the angle again
    EXPECT_EQ(app.enable_mask, 0x1);
    step_free_wheel0();
    EXPECT_EQ(app.enable_mask, 0x1);
}

// A wheel whose measured speed does not fall (here an encoder turning on its own at 50 rad/s):
// the outputs go off APP_STOP_TICKS after the setpoint reached 0, and stay off.
TEST_F(AppTest, StopTimesOutWhenTheWheelDoesNotSlowDown) {
    command_free_wheel0();
    for (int t = 0; t < 300; t++) step_free_wheel0();
    EXPECT_EQ(app.enable_mask, 0x1);
    send(PROTO_ID_STOP_ALL);
    int ticks = 0;
    while (app.enable_mask && ticks < 2000) {
        step_free_wheel0();
        ticks++;
    }
    // 5 ticks of ramp (the step sees the last one a tick later), then the time-out.
    EXPECT_EQ(ticks, 1 + 5 + static_cast<int>(APP_STOP_TICKS));
    for (int t = 0; t < 100; t++) step_free_wheel0();
    EXPECT_EQ(app.enable_mask, 0);
    EXPECT_EQ(app.w[0].drive_q15, 0);
}

}  // namespace

namespace {

// Records the calls the board's encoder reader gets: stages 0..4 of the next encoder, in order,
// once per wheel whatever path the wheel takes (closed, open loop, off).
struct RecordingIo {
    std::vector<int> calls;
    uint16_t words[4];
    uint16_t first() {
        calls.push_back(100);
        return words[0];
    }
    void next(uint8_t k) { calls.push_back(k); }
    uint16_t word(uint8_t i) {
        calls.push_back(200 + i);
        return words[i];
    }
};

std::vector<int> expected_calls() {
    std::vector<int> want = {100};
    for (int i = 0; i < 4; i++) {
        if (i) want.push_back(200 + i);
        for (int k = 0; k < APP_IO_STAGES; k++) want.push_back(k);
    }
    return want;
}

TEST_F(AppTest, EncoderStagesInOrderOnEveryPath) {
    set_param(PRM_HEARTBEAT_MS, 1000);
    send(PROTO_ID_SET_SPEEDS, i32s({5000, 0, -5000, 0}));  // wheels 1 and 3 stay off
    RecordingIo io;
    for (int i = 0; i < 4; i++) io.words[i] = enc_make_reply(static_cast<uint16_t>(100 * i), false);
    io.words[2] = enc_make_reply(7, true);  // a bad word on wheel 2
    app_control_step_io(&app, io);
    EXPECT_EQ(io.calls, expected_calls());
    EXPECT_EQ(app.enable_mask, 0x5);
}

TEST_F(AppTest, EncoderStagesInOrderInOpenLoop) {
    set_param(PRM_MODE, 1);
    set_param(PRM_HEARTBEAT_MS, 1000);
    send(PROTO_ID_SET_SPEEDS, i32s({5000, 0, 0, 0}));
    RecordingIo io = {};
    app_control_step_io(&app, io);
    EXPECT_EQ(io.calls, expected_calls());
    EXPECT_EQ(app.enable_mask, 0x1);
    EXPECT_EQ(app_speed_mrad_s(&app, 0), 0);  // the ramp is not part of the step
    app_setpoints_tick(&app);
    EXPECT_EQ(app_speed_mrad_s(&app, 0), 100);  // ramping at ACCEL 100 rad/s^2
}

// A STOP_ALL acted on early (the board's receive interrupt saw it behind queued frames): the
// SET_SPEEDS queued before it are dropped, the other frames answered, until the STOP_ALL's own
// turn acknowledges it; then setpoints are taken again.
TEST_F(AppTest, EarlyStopAllDropsTheSetpointsQueuedBeforeIt) {
    set_param(PRM_MODE, 1);
    send(PROTO_ID_SET_SPEEDS, i32s({10000, 10000, 10000, 10000}));
    step(5);
    app_note_stops_seen(&app, 1);
    EXPECT_EQ(app.w[0].target_mrad_s, 0);
    send(PROTO_ID_SET_SPEEDS, i32s({20000, 20000, 20000, 20000}));  // queued before the stop
    EXPECT_EQ(app.w[0].target_mrad_s, 0);
    send(PROTO_ID_PARAM_GET, {PRM_DECEL_RAD_S2});
    EXPECT_EQ(last(PROTO_ID_PARAM_VALUE)->payload[0], PRM_DECEL_RAD_S2);
    EXPECT_EQ(count(PROTO_ID_ERROR), 0);
    send(PROTO_ID_STOP_ALL);  // its own turn
    EXPECT_EQ(last(PROTO_ID_ACK)->payload[0], PROTO_ID_STOP_ALL);
    send(PROTO_ID_SET_SPEEDS, i32s({20000, 20000, 20000, 20000}));  // sent after the stop
    EXPECT_EQ(app.w[0].target_mrad_s, 20000);
}

// An RX overflow may have cut the STOP_ALL seen early out of the ring: setpoints are not held off
// waiting for a frame that will never be dispatched.
TEST_F(AppTest, RxOverflowEndsTheWaitForAnEarlyStopAll) {
    app_note_stops_seen(&app, 1);
    app_note_rx_overflow(&app, 1);
    app.flt.faults = 0;
    send(PROTO_ID_SET_SPEEDS, i32s({1000, 0, 0, 0}));
    EXPECT_EQ(app.w[0].target_mrad_s, 1000);
}

// The main loop reads the interrupt's count once per tick: a STOP_ALL dispatched before that is
// not acted on again (it would cancel the SET_SPEEDS sent after it), and setpoints are not held
// off waiting for it; the count wraps modulo 256.
TEST_F(AppTest, StopAllDispatchedBeforeTheCountIsReadIsNotActedOnTwice) {
    set_param(PRM_MODE, 1);
    for (int k = 0; k < 300; k++) {
        send(PROTO_ID_STOP_ALL);
        send(PROTO_ID_SET_SPEEDS, i32s({1000 + k, 0, 0, 0}));  // sent after the stop
        app_note_stops_seen(&app, static_cast<uint8_t>(k + 1));
        ASSERT_EQ(app.w[0].target_mrad_s, 1000 + k) << k;
    }
}

}  // namespace
