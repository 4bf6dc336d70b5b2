// Encoder words and the speed estimator: parity, wrap-around at 14 bits, fixed-point extremes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>

#include "enc.h"
#include "speed.h"

TEST(Enc, ParityOfKnownWords) {
    EXPECT_TRUE(enc_even_parity(0x0000));
    EXPECT_FALSE(enc_even_parity(0x0001));
    EXPECT_TRUE(enc_even_parity(0xFFFF));
    EXPECT_FALSE(enc_even_parity(0x7FFF));
}

TEST(Enc, ParseEveryAngleRoundTrips) {
    for (uint32_t a = 0; a < ENC_COUNTS; a++) {
        uint16_t out = 0xFFFF;
        ASSERT_EQ(enc_parse(enc_make_reply(static_cast<uint16_t>(a), false), &out), ENC_OK);
        ASSERT_EQ(out, a);
    }
}

TEST(Enc, ErrorFlagAndBadParityRejected) {
    uint16_t out = 1234;
    EXPECT_EQ(enc_parse(enc_make_reply(100, true), &out), ENC_ERROR);
    EXPECT_EQ(enc_parse(static_cast<uint16_t>(enc_make_reply(100, false) ^ 0x0004), &out),
              ENC_PARITY);
    EXPECT_EQ(enc_parse(static_cast<uint16_t>(enc_make_reply(100, false) ^ 0x8000), &out),
              ENC_PARITY);
    EXPECT_EQ(out, 1234);  // untouched on error
}

TEST(Enc, ClearErrorCommandIsAReadOfRegister1WithEvenParity) {
    EXPECT_EQ(ENC_CMD_CLEAR_ERROR & 0x3FFFu, 0x0001u);  // address of CLEAR ERROR FLAG
    EXPECT_NE(ENC_CMD_CLEAR_ERROR & 0x4000u, 0u);       // read
    EXPECT_TRUE(enc_even_parity(ENC_CMD_CLEAR_ERROR));  // bit 15 makes the parity even
    EXPECT_TRUE(enc_even_parity(ENC_CMD_READ_ANGLE));
}

TEST(Spd, WrapDeltaAcrossZeroAndExtremes) {
    EXPECT_EQ(spd_wrap_delta(16383, 0), 1);
    EXPECT_EQ(spd_wrap_delta(0, 16383), -1);
    EXPECT_EQ(spd_wrap_delta(16000, 300), 684);
    EXPECT_EQ(spd_wrap_delta(300, 16000), -684);
    EXPECT_EQ(spd_wrap_delta(0, 8191), 8191);
    EXPECT_EQ(spd_wrap_delta(0, 8192), -8192);  // half a turn is ambiguous: maps to -8192
    EXPECT_EQ(spd_wrap_delta(5, 5), 0);
}

TEST(Spd, WrapDeltaMatchesModularReference) {
    for (int a = 0; a < 16384; a += 97) {
        for (int d = -8192; d < 8192; d += 13) {
            int b = ((a + d) % 16384 + 16384) % 16384;
            ASSERT_EQ(spd_wrap_delta(static_cast<uint16_t>(a), static_cast<uint16_t>(b)), d);
        }
    }
}

// One count per 1 ms tick in mrad/s, and the q8 unit (1/256 count per tick).
static const double kMradPerCount = 2.0 * M_PI / 16384.0 * 1000.0 * 1000.0;
static const double kMradPerQ8 = kMradPerCount / 256.0;

TEST(Spd, Q8ToMradAgainstExactValueAtExtremes) {
    // |q8| <= 2^21 from the estimator; the conversion is specified up to 2^22.
    for (int32_t q : {-(1 << 22), -(1 << 21), -8192 * 256, -49979, -256, -1, 0, 1, 255, 256, 49979,
                      8191 * 256, 1 << 21, 1 << 22}) {
        double exact = q * kMradPerQ8;
        EXPECT_NEAR(spd_q8_to_mrad_s(q), exact, 1.0 + 1e-5 * fabs(exact)) << q;
        EXPECT_EQ(spd_q8_to_mrad_s(-q), -spd_q8_to_mrad_s(q)) << q;  // symmetric rounding
    }
    // Exactly the documented floor(|q8| * 98175 / 65536) with the sign applied.
    for (int64_t q = -(1 << 22); q <= (1 << 22); q += 977) {
        int64_t m = ((q < 0 ? -q : q) * 98175) >> 16;
        ASSERT_EQ(spd_q8_to_mrad_s(static_cast<int32_t>(q)), q < 0 ? -m : m) << q;
    }
}

TEST(Spd, MradToQ8AgainstExactValueAtExtremes) {
    for (int32_t v : {-(1 << 22), -400000, -74870, -1, 0, 1, 2, 74870, 157080, 400000, 1 << 22}) {
        double exact = v / kMradPerQ8;
        EXPECT_NEAR(spd_mrad_s_to_q8(v), exact, 1.0 + 5e-6 * fabs(exact)) << v;
        EXPECT_EQ(spd_mrad_s_to_q8(-v), -spd_mrad_s_to_q8(v)) << v;
    }
    for (int64_t v = -(1 << 22); v <= (1 << 22); v += 1009) {
        int64_t q = ((v < 0 ? -v : v) * 43748) >> 16;
        ASSERT_EQ(spd_mrad_s_to_q8(static_cast<int32_t>(v)), v < 0 ? -q : q) << v;
    }
    // The round trip loses at most 2 mrad/s (q8 unit 1.498 mrad/s) plus the constant's 4e-6.
    for (int32_t v = -400000; v <= 400000; v += 997) {
        ASSERT_NEAR(spd_q8_to_mrad_s(spd_mrad_s_to_q8(v)), v, 2.0 + 4.2e-6 * abs(v)) << v;
    }
}

TEST(Spd, GainIsPowerOfTwoAndClamped) {
    EXPECT_EQ(spd_gain(0), 0);  // stands for 256: no filtering
    for (uint8_t s = 1; s <= SPD_MAX_SHIFT; s++) EXPECT_EQ(spd_gain(s), 256 >> s) << int(s);
    EXPECT_EQ(spd_gain(9), 1);
    EXPECT_EQ(spd_gain(255), 1);
}

TEST(Spd, DivTicksMatchesDivisionAtExtremes) {
    const int32_t xs[] = {0,           1,         -1,         2,           -2,         3,
                          -3,          5,         -5,         3141592,     -3141592,   0x7FFFFFFF,
                          -0x7FFFFFFF, INT32_MIN, 0x55555555, -0x55555555, 0x7FFFFFFE, 1431655766};
    for (int32_t x : xs) {
        for (uint8_t d = 1; d <= 3; d++) {
            int64_t want = static_cast<int64_t>(x) / d;  // C division: towards zero
            ASSERT_EQ(spd_div_ticks(x, d), want) << x << " / " << int(d);
        }
    }
    for (int64_t x = -4000000; x <= 4000000; x += 7) {
        ASSERT_EQ(spd_div_ticks(static_cast<int32_t>(x), 3), x / 3) << x;
        ASSERT_EQ(spd_div_ticks(static_cast<int32_t>(x), 2), x / 2) << x;
    }
}

static void update(spd_state* s, int angle, uint8_t shift) {
    spd_update(s, static_cast<uint16_t>(((angle % 16384) + 16384) % 16384), spd_gain(shift));
}

// Runs at a constant step per tick and checks the 24-bit bounds of the filter on every update
// (the AVR multiply port_mul_s24_u8 needs |x - y| < 2^23; acc must stay within 2^29).
static int32_t run_constant_speed(int start, int step, int ticks, uint8_t shift) {
    spd_state s;
    spd_init(&s);
    int angle = start;
    for (int i = 0; i < ticks; i++) {
        update(&s, angle, shift);
        EXPECT_LE(std::abs(static_cast<long>(s.acc)), 1L << 29);
        angle += step;
    }
    return spd_q8(&s);
}

TEST(Spd, ConstantSpeedThroughWrapConvergesExactly) {
    // 715 rpm = 74.87 rad/s = 195.2 counts per tick; 195 counts/tick through many wraps.
    for (uint8_t shift = 0; shift <= SPD_MAX_SHIFT; shift++) {
        EXPECT_EQ(run_constant_speed(16300, 195, 4000, shift), 195 * 256);
        EXPECT_EQ(run_constant_speed(50, -195, 4000, shift), -195 * 256);
    }
}

TEST(Spd, ExtremeSpeedNoOverflowMaxShift) {
    // 8191 counts/tick is the largest unambiguous speed (30000 rpm); acc must not overflow.
    EXPECT_EQ(run_constant_speed(0, 8191, 8000, SPD_MAX_SHIFT), 8191 * 256);
    EXPECT_EQ(run_constant_speed(0, -8191, 8000, SPD_MAX_SHIFT), -8191 * 256);
    EXPECT_EQ(run_constant_speed(0, 8191, 8000, 200), 8191 * 256);  // shift clamped
    EXPECT_EQ(run_constant_speed(0, 8191, 8000, 0), 8191 * 256);
}

TEST(Spd, FullScaleReversalStaysWithin24Bits) {
    // The largest x - y of the filter: from +8191 counts/tick straight to -8192 and back.
    for (uint8_t shift = 0; shift <= SPD_MAX_SHIFT; shift++) {
        spd_state s;
        spd_init(&s);
        int angle = 0;
        for (int i = 0; i < 10000; i++) {
            int step = (i < 2000 && (i / 500) % 2 == 1) ? -8192 : 8191;
            int32_t y = spd_q8(&s);
            int32_t x = (s.primed ? step : 0) * 256;
            ASSERT_LT(std::abs(static_cast<long>(x) - y), 1L << 23) << i;
            angle += step;
            update(&s, angle, shift);
            ASSERT_LE(std::abs(static_cast<long>(s.acc)), 1L << 29);
            ASSERT_LE(std::abs(static_cast<long>(spd_q8(&s))), 1L << 21);
        }
        EXPECT_EQ(spd_q8(&s), 8191 * 256) << int(shift);
    }
}

TEST(Spd, FilterIsFirstOrderLowPass) {
    spd_state s;
    spd_init(&s);
    update(&s, 0, 3);
    update(&s, 100, 3);  // step of 100 counts/tick
    EXPECT_EQ(spd_q8(&s), 100 * 256 / 8);
}

TEST(Spd, FilterMatchesReferenceAcrossShiftChanges) {
    // Reference: acc += 2^(8 - shift) * (x - floor(acc / 256)), x = delta * 256, in int64 (it is
    // acc' = acc + x - (acc >> shift) with acc scaled by 2^(8 - shift)). A change of shift leaves
    // the estimate where it was (no jump): only the gain of the next updates changes.
    spd_state s;
    spd_init(&s);
    int64_t acc = 0;
    int angle = 0;
    update(&s, 0, 3);
    const uint8_t shifts[] = {3, 3, 5, 5, 0, 8, 8, 2, 2, 7};
    for (int i = 0; i < 400; i++) {
        uint8_t sh = shifts[(i / 17) % 10];
        int step = (i % 50) * 37 - 900;
        angle = ((angle + step) % 16384 + 16384) % 16384;
        int64_t x = static_cast<int64_t>(step) * 256;
        int64_t y = acc >= 0 ? acc / 256 : -((-acc + 255) / 256);
        acc = sh == 0 ? x * 256 : acc + (int64_t{1} << (8 - sh)) * (x - y);
        update(&s, angle, sh);
        ASSERT_EQ(s.acc, acc) << i;
    }
}

TEST(Spd, SkippedSampleSpansTheGap) {
    spd_state s;
    spd_init(&s);
    update(&s, 0, 0);
    update(&s, 200, 0);
    spd_skip(&s);        // tick with a bad word
    update(&s, 600, 0);  // 400 counts over 2 ticks
    EXPECT_EQ(spd_q8(&s), 200 * 256);
    update(&s, 700, 0);
    spd_skip(&s);
    spd_skip(&s);
    update(&s, 1000, 0);  // 300 counts over 3 ticks
    EXPECT_EQ(spd_q8(&s), 100 * 256);
    update(&s, 1000 - 7, 0);
    spd_skip(&s);
    spd_skip(&s);
    update(&s, 1000 - 7 - 1000, 0);  // -1000 / 3 rounded towards zero
    EXPECT_EQ(spd_q8(&s), -1000 * 256 / 3);
}

TEST(Spd, LongGapReprimes) {
    spd_state s;
    spd_init(&s);
    update(&s, 0, 0);
    update(&s, 100, 0);
    int32_t before = spd_q8(&s);
    for (int i = 0; i < 5; i++) spd_skip(&s);
    update(&s, 9000, 0);  // first sample after re-prime: estimate held
    EXPECT_EQ(spd_q8(&s), before);
    update(&s, 9100, 0);
    EXPECT_EQ(spd_q8(&s), 100 * 256);
}

TEST(Spd, MissedTicksSpanTheGap) {
    spd_state s;
    spd_init(&s);
    update(&s, 0, 0);
    update(&s, 200, 0);
    spd_missed_ticks(&s, 1);  // the main loop missed one tick: 400 counts over 2 ticks
    update(&s, 600, 0);
    EXPECT_EQ(spd_q8(&s), 200 * 256);
    spd_missed_ticks(&s, 1);  // a missed tick and a bad word: 3 ticks
    spd_skip(&s);
    update(&s, 600 - 900, 0);
    EXPECT_EQ(spd_q8(&s), -300 * 256);
    spd_missed_ticks(&s, 2);
    update(&s, 600 - 900 + 30, 0);
    EXPECT_EQ(spd_q8(&s), 10 * 256);
    int32_t before = spd_q8(&s);
    spd_missed_ticks(&s, 3);  // 4 ticks: re-prime, the estimate is held
    update(&s, 5000, 0);
    EXPECT_EQ(spd_q8(&s), before);
    update(&s, 5010, 0);
    EXPECT_EQ(spd_q8(&s), 10 * 256);
    spd_skip(&s);
    spd_missed_ticks(&s, 255);  // the largest count the main loop can pass
    update(&s, 0, 0);
    EXPECT_EQ(spd_q8(&s), 10 * 256);
}
