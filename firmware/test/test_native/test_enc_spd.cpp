// Encoder words and the speed estimator: parity, wrap-around at 14 bits, fixed-point extremes.
#include <gtest/gtest.h>

#include <cmath>

#include "enc.h"
#include "spd.h"

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

TEST(Spd, CountsToSpeedAgainstExactValue) {
    const double k = 2.0 * M_PI / 16384.0 * 1000.0 * 1000.0;  // mrad/s per count per ms
    for (int c : {-8192, -8191, -195, -1, 0, 1, 195, 819, 8191}) {
        double exact = c * k;
        EXPECT_NEAR(spd_counts_to_mrad_s(static_cast<int16_t>(c)), exact, 1.0 + 1e-5 * fabs(exact));
    }
    // Symmetric rounding: the sign never changes the magnitude.
    EXPECT_EQ(spd_counts_to_mrad_s(-8191), -spd_counts_to_mrad_s(8191));
}

TEST(Spd, CountsToSpeedAtInt16Extremes) {
    const double k = 98175.0 / 256.0;  // the documented conversion, truncated towards zero
    for (int c : {-32768, -32767, -8193, 8192, 32767}) {
        double want = c < 0 ? -floor(-c * k) : floor(c * k);
        EXPECT_EQ(spd_counts_to_mrad_s(static_cast<int16_t>(c)), static_cast<int32_t>(want)) << c;
    }
    for (int c = -32768; c <= 32767; c += 61) {
        int64_t exact = (static_cast<int64_t>(c < 0 ? -c : c) * 98175) >> 8;
        ASSERT_EQ(spd_counts_to_mrad_s(static_cast<int16_t>(c)), c < 0 ? -exact : exact) << c;
    }
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

static int32_t run_constant_speed(uint16_t start, int step, int ticks, uint8_t shift) {
    spd_state s;
    spd_init(&s);
    int32_t v = 0;
    int angle = start;
    for (int i = 0; i < ticks; i++) {
        v = spd_update(&s, static_cast<uint16_t>(((angle % 16384) + 16384) % 16384), shift);
        angle += step;
    }
    return v;
}

TEST(Spd, ConstantSpeedThroughWrapConvergesExactly) {
    // 715 rpm = 74.87 rad/s = 195.2 counts per tick; 195 counts/tick through many wraps.
    for (uint8_t shift = 0; shift <= SPD_MAX_SHIFT; shift++) {
        EXPECT_EQ(run_constant_speed(16300, 195, 4000, shift), spd_counts_to_mrad_s(195));
        EXPECT_EQ(run_constant_speed(50, -195, 4000, shift), spd_counts_to_mrad_s(-195));
    }
}

TEST(Spd, ExtremeSpeedNoOverflowMaxShift) {
    // 8191 counts/tick is the largest unambiguous speed (30000 rpm); acc must not overflow.
    EXPECT_EQ(run_constant_speed(0, 8191, 8000, SPD_MAX_SHIFT), spd_counts_to_mrad_s(8191));
    EXPECT_EQ(run_constant_speed(0, -8191, 8000, SPD_MAX_SHIFT), spd_counts_to_mrad_s(-8191));
    EXPECT_EQ(run_constant_speed(0, 8191, 8000, 200), spd_counts_to_mrad_s(8191));  // clamped
}

TEST(Spd, FilterIsFirstOrderLowPass) {
    spd_state s;
    spd_init(&s);
    spd_update(&s, 0, 3);
    int32_t first = spd_update(&s, 100, 3);  // step of 100 counts/tick
    EXPECT_EQ(first, spd_counts_to_mrad_s(100) / 8);
}

TEST(Spd, FilterShiftChangeMatchesReference) {
    // The estimator reuses its last output as acc >> shift; a shift change must not break that.
    spd_state s;
    spd_init(&s);
    int64_t acc = 0;
    int angle = 0;
    spd_update(&s, 0, 3);
    const uint8_t shifts[] = {3, 3, 5, 5, 0, 8, 8, 2, 2, 7};
    for (int i = 0; i < 400; i++) {
        uint8_t sh = shifts[(i / 17) % 10];
        int step = (i % 50) * 37 - 900;
        angle = ((angle + step) % 16384 + 16384) % 16384;
        int32_t raw = spd_counts_to_mrad_s(static_cast<int16_t>(step));
        acc += raw - (acc >> sh);
        ASSERT_EQ(spd_update(&s, static_cast<uint16_t>(angle), sh), acc >> sh) << i;
    }
}

TEST(Spd, SkippedSampleSpansTheGap) {
    spd_state s;
    spd_init(&s);
    spd_update(&s, 0, 0);
    spd_update(&s, 200, 0);
    spd_skip(&s);                        // tick with a bad word
    int32_t v = spd_update(&s, 600, 0);  // 400 counts over 2 ticks
    EXPECT_EQ(v, spd_counts_to_mrad_s(400) / 2);
}

TEST(Spd, LongGapReprimes) {
    spd_state s;
    spd_init(&s);
    spd_update(&s, 0, 0);
    spd_update(&s, 100, 0);
    int32_t before = s.speed_mrad_s;
    for (int i = 0; i < 5; i++) spd_skip(&s);
    EXPECT_EQ(spd_update(&s, 9000, 0), before);  // first sample after re-prime: estimate held
    EXPECT_EQ(spd_update(&s, 9100, 0), spd_counts_to_mrad_s(100));
}
