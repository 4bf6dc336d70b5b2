// PI controller (saturation, slew, anti-windup, fixed-point extremes) and setpoint ramps.
#include <gtest/gtest.h>

#include <climits>
#include <cstdlib>

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

// ---- the PI against a reference with int32 arithmetic throughout, the plainest form of the
// controller: the step on the error's sign and 16-bit magnitude, mirrored for a
// negative error and with 24-bit intermediates, must give the same output, integrator and
// saturation flag for every state, gain and error, including a shrinking out_max.
namespace {
struct RefPi {
    int32_t integ = 0;
    int16_t out = 0;
    uint8_t saturated = 0;
};

int32_t clamp32(int32_t x, int32_t lo, int32_t hi) {
    if (x < lo) return lo;
    if (x > hi) return hi;
    return x;
}

int16_t ref_pi_step(RefPi* s, const pi_gains* g, int32_t setpoint, int32_t measured) {
    int32_t e32 = setpoint - measured;
    const bool neg = e32 < 0;
    uint16_t mag;
    if (e32 > PI_ERR_CLAMP || e32 < -PI_ERR_CLAMP) {
        mag = static_cast<uint16_t>(PI_ERR_CLAMP);
    } else {
        mag = static_cast<uint16_t>(neg ? -e32 : e32);
    }
    uint32_t p = static_cast<uint32_t>(g->kp_q8) * mag;
    int32_t p8 = neg ? -static_cast<int32_t>((p + 255u) >> 8) : static_cast<int32_t>(p >> 8);
    const int16_t out_max = g->out_max < 0 ? 0 : g->out_max;
    const int16_t slew = g->slew < 1 ? 1 : g->slew;
    const int16_t out = s->out;
    int16_t lo =
        out >= slew - out_max ? static_cast<int16_t>(out - slew) : static_cast<int16_t>(-out_max);
    int16_t hi = out <= out_max - slew ? static_cast<int16_t>(out + slew) : out_max;
    if (lo > hi) lo = hi;
    const int32_t ilim = static_cast<int32_t>(out_max) << 8;
    uint32_t di = static_cast<uint32_t>(g->ki_q8) * mag;
    const uint32_t di_max = static_cast<uint32_t>(ilim) << 1;
    if (di > di_max) di = di_max;
    int32_t integ = neg ? s->integ - static_cast<int32_t>(di) : s->integ + static_cast<int32_t>(di);
    integ = clamp32(integ, -ilim, ilim);
    int32_t u = p8 + (integ >> 8);
    if (!neg && mag != 0 && u > hi) {
        int32_t cap = clamp32(hi - p8, -out_max, out_max) * 256;
        integ = cap > s->integ ? cap : s->integ;
        if (integ > ilim) integ = ilim;
        u = p8 + (integ >> 8);
    } else if (neg && u < lo) {
        int32_t cap = clamp32(lo - p8, -out_max, out_max) * 256;
        integ = cap < s->integ ? cap : s->integ;
        if (integ < -ilim) integ = -ilim;
        u = p8 + (integ >> 8);
    }
    s->integ = integ;
    int16_t y;
    if (u > hi) {
        y = hi;
    } else if (u < lo) {
        y = lo;
    } else {
        y = static_cast<int16_t>(u);
    }
    s->saturated = (y != u) ? 1 : 0;
    s->out = y;
    return y;
}

uint32_t lcg(uint32_t* x) {
    *x = *x * 1664525u + 1013904223u;
    return *x >> 8;
}
}  // namespace

TEST(Pi, MatchesReferenceOverRandomSequencesAndExtremes) {
    const uint16_t gains[] = {0, 1, 2, 80, 255, 256, 1000, 32767, 32768, 65535};
    const int16_t limits[] = {0, 1, 100, 10000, 16384, 32767};
    const int32_t errors[] = {0,     1,      -1,     255,     -256,    65535,     -65535,
                              65536, -65536, 300000, -300000, 1 << 29, -(1 << 29)};
    uint32_t rnd = 12345;
    long steps = 0;
    for (int run = 0; run < 3000; run++) {
        pi_gains g = {gains[lcg(&rnd) % 10], gains[lcg(&rnd) % 10], limits[lcg(&rnd) % 6],
                      static_cast<int16_t>(1 + lcg(&rnd) % 32767)};
        if (run % 3 == 0) g.slew = limits[lcg(&rnd) % 6] == 0 ? 1 : limits[lcg(&rnd) % 6];
        pi_state s;
        pi_reset(&s);
        RefPi r;
        for (int k = 0; k < 60; k++) {
            int32_t e = (lcg(&rnd) % 4 == 0) ? errors[lcg(&rnd) % 13]
                                             : static_cast<int32_t>(lcg(&rnd) % 140001) - 70000;
            if (k == 30) g.out_max = limits[lcg(&rnd) % 6];  // limits change while running
            if (k == 45) g.ki_q8 = gains[lcg(&rnd) % 10];
            int16_t want = ref_pi_step(&r, &g, e, 0);
            int16_t got = pi_step(&s, &g, e, 0);
            ASSERT_EQ(got, want) << "run " << run << " step " << k << " e " << e;
            ASSERT_EQ(s.integ, r.integ) << "run " << run << " step " << k;
            ASSERT_EQ(s.saturated, r.saturated) << "run " << run << " step " << k;
            ASSERT_LE(std::abs(static_cast<long>(s.integ)), 32767L * 256);  // 24 bits
            steps++;
        }
    }
    EXPECT_EQ(steps, 180000);
}

TEST(Pi, SignedErrorStepEqualsMagnitudeStep) {
    // pi_step_err on the signed error is what the control step calls; pi_step_mag_c is its core.
    pi_gains g = pi_gains_sanitize({300, 7, 20000, 500});
    pi_state a, b;
    pi_reset(&a);
    pi_reset(&b);
    for (int32_t e : {0, 5, -5, 65535, -65535, 1200, -30000, 0, 17}) {
        bool neg = e < 0;
        EXPECT_EQ(pi_step_err_c(&a, &g, e),
                  pi_step_mag_c(&b, &g, neg, static_cast<uint16_t>(neg ? -e : e)));
        EXPECT_EQ(a.integ, b.integ);
        EXPECT_EQ(a.saturated, b.saturated);
    }
}

// The clamp of the signed error at +-65535 and its sign, against values worked out by hand:
// kp = 256 (P = e exactly), ki = 0, limits wide open (out_max 32767, slew 32767), state reset.
TEST(Pi, SignedErrorClampAndSign) {
    const pi_gains g = {256, 0, 32767, 32767};
    struct Case {
        int32_t e;
        int16_t y;
        uint8_t sat;
    };
    // |P| <= 32767 passes; beyond, the output limit holds (P = +-65535 after the clamp of e).
    const Case cases[] = {{0, 0, 0},
                          {1, 1, 0},
                          {-1, -1, 0},
                          {32767, 32767, 0},
                          {-32767, -32767, 0},
                          {32768, 32767, 1},
                          {-32768, -32767, 1},
                          {65535, 32767, 1},
                          {-65535, -32767, 1},
                          {65536, 32767, 1},
                          {-65536, -32767, 1},
                          {INT32_MAX, 32767, 1},
                          {INT32_MIN + 1, -32767, 1}};
    for (const Case& c : cases) {
        pi_state s;
        pi_reset(&s);
        EXPECT_EQ(pi_step_err_c(&s, &g, c.e), c.y) << "e " << c.e;
        EXPECT_EQ(s.saturated, c.sat) << "e " << c.e;
        EXPECT_EQ(s.integ, 0) << "e " << c.e;
    }
    // The clamp itself: with kp = 1, P = floor(E / 256), so E = +-65535 gives 255 and -256, and
    // every error beyond gives the same (not 256 or -257 as the unclamped error would).
    const pi_gains g1 = {1, 0, 32767, 32767};
    const int32_t beyond[] = {65535, 65536, 65791, 1 << 24, INT32_MAX};
    for (int32_t e : beyond) {
        pi_state s;
        pi_reset(&s);
        EXPECT_EQ(pi_step_err_c(&s, &g1, e), 255) << "e " << e;
        pi_reset(&s);
        EXPECT_EQ(pi_step_err_c(&s, &g1, -e), -256) << "e " << -e;
    }
    // The integrator sees the clamped error too: ki = 65535, out_max 32767: di = 65535 * 65535 is
    // clamped to 2 * ilim, the sum to ilim = 32767 * 256 whatever the error beyond the clamp.
    const pi_gains gi = {0, 65535, 32767, 32767};
    for (int32_t e : {65535, 70000, INT32_MAX}) {
        pi_state s;
        pi_reset(&s);
        pi_step_err_c(&s, &gi, e);
        EXPECT_EQ(s.integ, 32767L * 256) << "e " << e;
        pi_reset(&s);
        pi_step_err_c(&s, &gi, -e);
        EXPECT_EQ(s.integ, -32767L * 256) << "e " << -e;
    }
    // Unsigned gains above 32767: kp = 40000, e = 100: P = floor(4,000,000 / 256) = 15625 and
    // -15625 for e = -100 (floor of -15625 exactly).
    const pi_gains gk = {40000, 0, 32767, 32767};
    pi_state s;
    pi_reset(&s);
    EXPECT_EQ(pi_step_err_c(&s, &gk, 100), 15625);
    pi_reset(&s);
    EXPECT_EQ(pi_step_err_c(&s, &gk, -100), -15625);
    pi_reset(&s);
    EXPECT_EQ(pi_step_err_c(&s, &gk, -101), -15782);  // floor(-15781.25)
}
