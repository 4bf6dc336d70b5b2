// Sensor and motion supervision (grd), the electrical zero found by CALIBRATE_ENC (cal) on a
// simulated motor, the offsets rule after PARAMS_DEFAULTED and CLEAR_FAULTS with a mask.
#include <gtest/gtest.h>

#include <cmath>

#include "app.h"
#include "cal.h"
#include "commut.h"
#include "enc.h"
#include "guard.h"
#include "test_support.h"

namespace {

using Bytes = std::vector<uint8_t>;

grd_limits limits() {
    grd_limits l;
    l.drive_min_q15 = 8192;
    l.fault_ticks = 50;
    l.dead_ticks = 5;
    l.stall_q8 = 1335;   // 2 rad/s
    l.margin_q8 = 6676;  // 10 rad/s
    l.over_q8 = 111538;  // 157.08 + 10 rad/s
    return l;
}

TEST(Guard, DeadWordWhileDrivenLatchesAfterTheLimitNotAtRest) {
    grd_limits l = limits();
    grd_wheel g;
    grd_reset(&g);
    for (int t = 0; t < 100; t++) EXPECT_EQ(grd_sensor(&g, &l, 0, true, false), 0) << t;
    for (int t = 1; t < 5; t++) EXPECT_EQ(grd_sensor(&g, &l, 0, true, true), 0) << t;
    EXPECT_EQ(grd_sensor(&g, &l, 0, true, true), PROTO_FAULT_ENC_STUCK);
    grd_reset(&g);
    for (int t = 0; t < 10; t++)
        EXPECT_EQ(grd_sensor(&g, &l, 0x3FFF, true, true), t >= 5 ? PROTO_FAULT_ENC_STUCK : 0);
    grd_reset(&g);  // any other word frozen under drive is left to the stall check
    for (int t = 0; t < 1000; t++) EXPECT_EQ(grd_sensor(&g, &l, 1234, true, true), 0);
    grd_reset(&g);  // a slow wheel passing through 0: the word changes
    for (int t = 0; t < 100; t++) {
        EXPECT_EQ(grd_sensor(&g, &l, static_cast<uint16_t>((t / 3) & ENC_MASK), true, true), 0);
    }
}

TEST(Guard, DiagnosticsRegisterBadTwiceInARowLatches) {
    grd_wheel g;
    grd_reset(&g);
    const uint16_t good = enc_make_reply(0x0100 | 0x40, false);  // OCF, AGC 64
    EXPECT_EQ(grd_diag(&g, good), 0);
    for (uint16_t bad : {0x0000u, 0xFFFFu, 0x0040u, 0x0300u, 0x0500u, 0x0900u}) {
        const uint16_t word = bad == 0xFFFFu ? bad : enc_make_reply(bad, false);
        EXPECT_EQ(grd_diag(&g, word), 0) << std::hex << bad;
        EXPECT_EQ(grd_diag(&g, word), PROTO_FAULT_ENC_DIAG) << std::hex << bad;
        EXPECT_EQ(grd_diag(&g, good), 0);
    }
    EXPECT_EQ(grd_diag(&g, static_cast<uint16_t>(good ^ 0x8000u)), 0);  // parity: one bad read
    EXPECT_EQ(grd_diag(&g, enc_make_reply(0x0100, true)), PROTO_FAULT_ENC_DIAG);  // error flag
}

TEST(Guard, StallNeedsSaturatedHardDriveAndAStillWheelForTheWholeTime) {
    grd_limits l = limits();
    grd_wheel g;
    grd_reset(&g);
    for (int t = 1; t < 50; t++) EXPECT_EQ(grd_motion(&g, &l, true, true, 16384, 100, 5000), 0);
    EXPECT_EQ(grd_motion(&g, &l, true, true, 16384, 100, 5000), PROTO_FAULT_STALL);
    grd_reset(&g);
    for (int t = 0; t < 200; t++) {  // not saturated, drive low, or not looping: never
        EXPECT_EQ(grd_motion(&g, &l, true, false, 16384, 0, 5000), 0);
        EXPECT_EQ(grd_motion(&g, &l, true, true, 4000, 0, 5000), 0);
        EXPECT_EQ(grd_motion(&g, &l, false, true, 16384, 0, 5000), 0);
    }
    grd_reset(&g);  // crossing zero while reversing at 100 rad/s^2 (67 q8 per tick): moves on
    for (int t = 0; t < 40; t++) {
        EXPECT_EQ(grd_motion(&g, &l, true, true, -16384, 1300 - 67 * t, -50000), 0) << t;
    }
}

TEST(Guard, RunawayAgainstTheSetpointOrAboveTheMaximum) {
    grd_limits l = limits();
    grd_wheel g;
    grd_reset(&g);
    int latched_at = -1;
    for (int t = 0; t < 200 && latched_at < 0; t++) {  // accelerating the wrong way
        if (grd_motion(&g, &l, true, true, 16384, -7000 - 100 * t, 13350) & PROTO_FAULT_RUNAWAY) {
            latched_at = t;
        }
    }
    EXPECT_EQ(latched_at, 49);
    grd_reset(&g);  // braking back towards a reversed setpoint: coming closer, never latches
    for (int t = 0; t < 500; t++) {
        EXPECT_EQ(grd_motion(&g, &l, true, true, -16384, 60000 - 100 * t, -50000), 0) << t;
    }
    grd_reset(&g);
    for (int t = 1; t < 50; t++) EXPECT_EQ(grd_motion(&g, &l, true, false, 100, 112000, 100000), 0);
    EXPECT_EQ(grd_motion(&g, &l, true, false, 100, 112000, 100000), PROTO_FAULT_RUNAWAY);
}

// Calibration on the simulated motor, returning the outcome and the offset found.
uint8_t calibrate(Motor& m, uint16_t* offset, bool reversed_wiring = false) {
    cal_state c;
    cal_begin(&c, static_cast<uint8_t>(m.pp));
    for (unsigned t = 0; t <= CAL_TOTAL_TICKS + 5; t++) {
        uint16_t duty[3];
        cmt_phases(c.out, 6000, duty);
        if (reversed_wiring) {
            const uint16_t b = duty[1];
            duty[1] = duty[2];
            duty[2] = b;
        }
        m.run(duty, true, 1e-3);
        uint16_t angle = 0;
        (void)enc_parse(m.word(), &angle);
        const uint8_t r = cal_tick(&c, angle, offset);
        if (r != CAL_RUNNING) return r;
    }
    return CAL_RUNNING;
}

TEST(Calibration, FindsTheOffsetThatMakesTheElectricalAngleRight) {
    for (double elec_deg : {0.0, 150.0, 275.0}) {
        Motor m;
        m.elec = elec_deg * M_PI / 180.0;
        uint16_t offset = 0;
        ASSERT_EQ(calibrate(m, &offset), CAL_DONE) << elec_deg;
        // cmt_elec_angle(mech) = mech * 4 pp - offset must equal the rotor's electrical angle
        // pp * theta + elec everywhere: at mech 0 it is -offset.
        const double want = fmod(360.0 - elec_deg, 360.0) / 360.0 * 65536.0;
        double err = fmod(offset - want + 3 * 65536.0 + 32768.0, 65536.0) - 32768.0;
        EXPECT_LT(fabs(err), 65536.0 * 3.0 / 360.0) << elec_deg << " offset " << offset;
    }
}

TEST(Calibration, FailsWithANamedReason) {
    Motor stuck;
    stuck.j = 1e3;  // does not move
    uint16_t offset = 0;
    EXPECT_EQ(calibrate(stuck, &offset), PROTO_CAL_NOT_MOVED);
    Motor reversed;
    EXPECT_EQ(calibrate(reversed, &offset, true), PROTO_CAL_REVERSED);
    Motor wrong_pp;
    wrong_pp.pp = 11;  // the board believes 7
    cal_state c;
    cal_begin(&c, 7);
    uint8_t r = CAL_RUNNING;
    for (unsigned t = 0; t <= CAL_TOTAL_TICKS && r == CAL_RUNNING; t++) {
        uint16_t duty[3];
        cmt_phases(c.out, 6000, duty);
        wrong_pp.run(duty, true, 1e-3);
        uint16_t angle = 0;
        (void)enc_parse(wrong_pp.word(), &angle);
        r = cal_tick(&c, angle, &offset);
    }
    EXPECT_EQ(r, PROTO_CAL_POLE_PAIRS);
}

class AppRules : public ::testing::Test {
   protected:
    app_state app;
    void SetUp() override {
        FakeEeprom::erase();  // blank: PARAMS_DEFAULTED, offsets uncalibrated
        FakeEeprom::busy_polls = 0;
        TxCapture::reset();
        app_init(&app, &FakeEeprom::iface, TxCapture::tx, 0);
        TxCapture::frames.clear();
    }
    void send(uint8_t id, const Bytes& payload = {}) {
        uint8_t out[PROTO_MAX_WIRE];
        uint8_t n = proto_build(id, payload.data(), static_cast<uint8_t>(payload.size()), out);
        for (uint8_t i = 0; i < n; i++) app_rx_byte(&app, out[i]);
    }
    void send_u16(uint8_t id, uint16_t v) {
        uint8_t p[2];
        proto_put_u16(p, v);
        send(id, Bytes(p, p + 2));
    }
    void set_speeds(int32_t w0, int32_t w1) {
        Bytes p(16, 0);
        proto_put_i32(&p[0], w0);
        proto_put_i32(&p[4], w1);
        send(PROTO_ID_SET_SPEEDS, p);
    }
    void set_param(uint8_t id, int32_t v) {
        Bytes p(5, 0);
        p[0] = id;
        proto_put_i32(&p[1], v);
        send(PROTO_ID_PARAM_SET, p);
    }
    const RxFrame* last() const {
        return TxCapture::frames.empty() ? nullptr : &TxCapture::frames.back();
    }
    void expect_error(uint8_t req, uint8_t code, uint8_t detail) {
        ASSERT_NE(last(), nullptr);
        EXPECT_EQ(last()->id, PROTO_ID_ERROR);
        EXPECT_EQ(last()->payload, (std::vector<uint8_t>{req, code, detail}));
    }
};

TEST_F(AppRules, DefaultedOffsetsRefuseClosedLoopSetpointsUntilSet) {
    EXPECT_TRUE(app.flt.faults & PROTO_FAULT_PARAMS_DEFAULTED);
    set_speeds(0, 0);  // zero is accepted
    EXPECT_TRUE(TxCapture::frames.empty());
    set_speeds(5000, 0);
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_OFFSET_UNCALIBRATED, 0);
    send_u16(PROTO_ID_CLEAR_FAULTS, 0xFFFF);  // clearing the fault does not set an offset
    set_speeds(5000, 0);
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_OFFSET_UNCALIBRATED, 0);
    set_param(PRM_ENC_OFFSET_M0, 1234);
    set_speeds(5000, 0);
    EXPECT_EQ(last()->id, PROTO_ID_PARAM_VALUE);  // accepted: no reply
    set_speeds(5000, 5000);
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_OFFSET_UNCALIBRATED, 1);
    set_param(PRM_MODE, 1);  // open loop needs no offsets
    set_speeds(5000, 5000);
    EXPECT_EQ(last()->id, PROTO_ID_PARAM_VALUE);
}

TEST_F(AppRules, ClearFaultsClearsOnlyTheNamedBits) {
    flt_set(&app.flt, PROTO_FAULT_ENCODER_M1 | PROTO_FAULT_ENC_DIAG | PROTO_FAULT_RX_OVERFLOW);
    EXPECT_TRUE(flt_wheel_disabled(&app.flt, 1));
    send_u16(PROTO_ID_CLEAR_FAULTS, PROTO_FAULT_ENCODER_M1 | PROTO_FAULT_ENC_DIAG);
    EXPECT_EQ(last()->id, PROTO_ID_ACK);
    EXPECT_EQ(app.flt.faults, PROTO_FAULT_RX_OVERFLOW | PROTO_FAULT_PARAMS_DEFAULTED);
    EXPECT_FALSE(flt_wheel_disabled(&app.flt, 1));
    flt_set(&app.flt, PROTO_FAULT_RUNAWAY);
    for (uint8_t w = 0; w < 4; w++) EXPECT_TRUE(flt_wheel_disabled(&app.flt, w));
}

TEST_F(AppRules, CalibrateEncRunsOnTheMotorStoresTheOffsetAndUnblocks) {
    set_param(PRM_HEARTBEAT_MS, 1000);
    Motor m[4];
    m[2].elec = 150.0 * M_PI / 180.0;
    send(PROTO_ID_CALIBRATE_ENC, {9});
    expect_error(PROTO_ID_CALIBRATE_ENC, PROTO_ERR_CALIBRATION_FAILED, PROTO_CAL_BAD_WHEEL);
    TxCapture::frames.clear();
    send(PROTO_ID_CALIBRATE_ENC, {2});
    set_speeds(1000, 0);
    expect_error(PROTO_ID_SET_SPEEDS, PROTO_ERR_BUSY, 2);
    TxCapture::frames.clear();
    unsigned t = 0;
    for (; t < CAL_TOTAL_TICKS + 10 && TxCapture::frames.empty(); t++) {
        uint16_t words[4];
        for (int i = 0; i < 4; i++) words[i] = m[i].word();
        app_step_alive(&app, words);
        for (int i = 0; i < 4; i++) m[i].run(app.pwm[i], (app.enable_mask >> i) & 1, 1e-3);
        if (t == 10) {
            EXPECT_EQ(app.enable_mask, 0x4);  // only the calibrated wheel
        }
    }
    ASSERT_FALSE(TxCapture::frames.empty()) << "no reply after " << t << " ticks";
    EXPECT_EQ(last()->id, PROTO_ID_ACK);
    EXPECT_EQ(last()->payload[0], PROTO_ID_CALIBRATE_ENC);
    EXPECT_EQ(app.uncal_mask, 0x0B);
    // The stop logic sees the wheel at rest once its window of angles is full.
    for (unsigned k = 0; k < APP_STOP_WINDOW + 1; k++) {
        const uint16_t rest[4] = {m[0].word(), m[1].word(), m[2].word(), m[3].word()};
        app_step_alive(&app, rest);
    }
    EXPECT_EQ(app.enable_mask, 0);
    const double want = 210.0 / 360.0 * 65536.0;
    const double err =
        fmod(app.prm.v[PRM_ENC_OFFSET_M2] - want + 3 * 65536.0 + 32768.0, 65536.0) - 32768.0;
    EXPECT_LT(fabs(err), 65536.0 * 3.0 / 360.0);
    // The loop now holds wheel 2 at 20 rad/s without a fault.
    set_param(PRM_DRIVE_MAX_Q15, 32767);
    Bytes p(16, 0);
    proto_put_i32(&p[8], 20000);
    send(PROTO_ID_SET_SPEEDS, p);
    double mean = 0;
    for (int k = 0; k < 4000; k++) {
        uint16_t words[4];
        for (int i = 0; i < 4; i++) words[i] = m[i].word();
        app_step_alive(&app, words);
        for (int i = 0; i < 4; i++) m[i].run(app.pwm[i], (app.enable_mask >> i) & 1, 1e-3);
        if (k >= 3000) mean += m[2].omega / 1000.0;
    }
    EXPECT_NEAR(mean, 20.0, 0.1);
    EXPECT_EQ(app.flt.faults & ~PROTO_FAULT_PARAMS_DEFAULTED, 0);
}

TEST_F(AppRules, WrongOffsetRunsAwayAndLatchesRunawayWithAllDriversOff) {
    set_param(PRM_HEARTBEAT_MS, 1000);
    set_param(PRM_ENC_OFFSET_M0, 0);
    Motor m[4];
    m[0].elec = 150.0 * M_PI / 180.0;
    set_speeds(20000, 0);
    int t = 0;
    for (; t < 3000 && !(app.flt.faults & PROTO_FAULT_RUNAWAY); t++) {
        uint16_t words[4];
        for (int i = 0; i < 4; i++) words[i] = m[i].word();
        app_step_alive(&app, words);
        for (int i = 0; i < 4; i++) m[i].run(app.pwm[i], (app.enable_mask >> i) & 1, 1e-3);
    }
    ASSERT_TRUE(app.flt.faults & PROTO_FAULT_RUNAWAY) << m[0].omega;
    EXPECT_GT(m[0].omega, -40.0);
    const uint16_t words[4] = {m[0].word(), m[1].word(), m[2].word(), m[3].word()};
    app_step_alive(&app, words);
    EXPECT_EQ(app.enable_mask, 0);
}

}  // namespace
