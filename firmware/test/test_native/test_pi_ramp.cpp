// PI controller (saturation, slew, anti-windup, fixed-point extremes) and setpoint ramps.
#include <gtest/gtest.h>

#include <climits>

#include "pi.h"
#include "ramp.h"

static const pi_gains kG = {256, 0, 10000, 32767};  // kp = 1 Q15 count per mrad/s

TEST(Pi, ProportionalOnly) {
    pi_state s;
    pi_reset(&s);
    EXPECT_EQ(pi_step(&s, &kG, 1000, 0), 1000);
    EXPECT_EQ(pi_step(&s, &kG, 0, 1000), -1000);
    EXPECT_EQ(s.saturated, 0);
}

TEST(Pi, OutputLimitBothSigns) {
    pi_state s;
    pi_reset(&s);
    EXPECT_EQ(pi_step(&s, &kG, 50000, 0), 10000);
    EXPECT_EQ(s.saturated, 1);
    EXPECT_EQ(pi_step(&s, &kG, -50000, 0), -10000);
}

TEST(Pi, SlewLimit) {
    pi_gains g = kG;
    g.slew = 100;
    pi_state s;
    pi_reset(&s);
    EXPECT_EQ(pi_step(&s, &g, 5000, 0), 100);
    EXPECT_EQ(pi_step(&s, &g, 5000, 0), 200);
    EXPECT_EQ(pi_step(&s, &g, -5000, 0), 100);
    EXPECT_EQ(s.saturated, 1);
}

TEST(Pi, IntegralReachesSteadyState) {
    pi_gains g = {0, 256, 32767, 32767};  // I += e per tick
    pi_state s;
    pi_reset(&s);
    for (int i = 0; i < 10; i++) pi_step(&s, &g, 100, 0);
    EXPECT_EQ(s.out, 1000);
}

TEST(Pi, AntiWindupRecoversAtOnce) {
    pi_gains g = {256, 256, 10000, 32767};
    pi_state s;
    pi_reset(&s);
    for (int i = 0; i < 100000; i++) pi_step(&s, &g, 60000, 0);  // long saturation
    EXPECT_EQ(s.out, 10000);
    EXPECT_LE(s.integ, 10000L * 256);
    // Error reverses: without anti-windup the output would stay at the limit for a long time.
    int16_t u = pi_step(&s, &g, 0, 5000);
    EXPECT_LT(u, 10000);
    int steps = 1;
    while (pi_step(&s, &g, 0, 5000) > 0) steps++;
    EXPECT_LT(steps, 50);
}

TEST(Pi, NoWindupWhileSlewLimited) {
    pi_gains g = {0, 256, 32767, 10};
    pi_state s;
    pi_reset(&s);
    for (int i = 0; i < 100; i++) pi_step(&s, &g, 10000, 0);
    EXPECT_EQ(s.out, 1000);
    // The integrator did not run ahead of the slew-limited output.
    EXPECT_LE(s.integ >> 8, 1000);
}

TEST(Pi, ExtremeGainsAndErrorsDoNotOverflow) {
    pi_gains g = {32767, 32767, 32767, 32767};
    pi_state s;
    pi_reset(&s);
    const int32_t big[] = {INT32_MAX / 4, -INT32_MAX / 4, 3000000, -3000000, 65535, -65536};
    for (int32_t e : big) {
        pi_step(&s, &g, e, 0);  // a sign reversal takes two steps at the largest slew
        int16_t u = pi_step(&s, &g, e, 0);
        EXPECT_GE(u, -32767);
        EXPECT_LE(u, 32767);
        EXPECT_EQ(u, e > 0 ? 32767 : -32767);
    }
}

TEST(Pi, OutMaxShrinkMovesTowardsLimit) {
    pi_state s;
    pi_reset(&s);
    pi_gains g = kG;
    pi_step(&s, &g, 8000, 0);
    g.out_max = 1000;
    EXPECT_EQ(pi_step(&s, &g, 8000, 0), 1000);
}

TEST(Ramp, StepsAndArrives) {
    EXPECT_EQ(ramp_step(0, 1000, 300), 300);
    EXPECT_EQ(ramp_step(900, 1000, 300), 1000);
    EXPECT_EQ(ramp_step(0, -1000, 300), -300);
    EXPECT_EQ(ramp_step(-900, -1000, 300), -1000);
    EXPECT_EQ(ramp_step(5, 5, 300), 5);
    EXPECT_EQ(ramp_step(0, 10, 0), 1);  // non-positive step still converges
}

TEST(Ramp, Int32ExtremesDoNotOverflow) {
    EXPECT_EQ(ramp_step(INT32_MIN, INT32_MAX, 1000), INT32_MIN + 1000);
    EXPECT_EQ(ramp_step(INT32_MAX, INT32_MIN, 1000), INT32_MAX - 1000);
    EXPECT_EQ(ramp_step(INT32_MAX - 5, INT32_MAX, 1000), INT32_MAX);
    EXPECT_EQ(ramp_step(INT32_MIN + 5, INT32_MIN, INT32_MAX), INT32_MIN);
}

TEST(Ramp, TimeToReachMatchesRate) {
    // 100 rad/s^2 = 100 mrad/s per tick: 0 -> 74870 mrad/s takes ceil(748.7) = 749 ticks.
    int32_t v = 0;
    int ticks = 0;
    while (v != 74870) {
        v = ramp_step(v, 74870, 100);
        ticks++;
    }
    EXPECT_EQ(ticks, 749);
}
