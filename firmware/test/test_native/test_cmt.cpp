// Commutation: sine table, electrical angle wrap, duty range, space-vector direction, phase rate.
#include <gtest/gtest.h>

#include <cmath>

#include "cmt.h"

TEST(Cmt, TableMatchesSine) {
    for (int i = 0; i < CMT_TABLE_SIZE; i++) {
        ASSERT_NEAR(cmt_sine_q15[i], 32767.0 * sin(2 * M_PI * i / 256), 0.5) << "entry " << i;
    }
}

TEST(Cmt, ElecAngleWrapsModulo) {
    for (uint32_t m = 0; m < 16384; m += 7) {
        for (uint8_t pp : {1, 7, 14, 40}) {
            uint32_t expect = (m * 4u * pp - 1000u) & 0xFFFFu;
            ASSERT_EQ(cmt_elec_angle(static_cast<uint16_t>(m), pp, 1000), expect);
        }
    }
    EXPECT_EQ(cmt_elec_angle(0xFFFF, 7, 0), cmt_elec_angle(0x3FFF, 7, 0));  // top bits ignored
}

static void vector_of(const uint16_t d[3], double* mag, double* ang) {
    double a = d[0] - 400.0, b = d[1] - 400.0, c = d[2] - 400.0;
    double alpha = (2.0 / 3.0) * (a - 0.5 * (b + c));
    double beta = (b - c) / sqrt(3.0);
    *mag = hypot(alpha, beta);
    *ang = atan2(beta, alpha);
}

TEST(Cmt, DutiesInRangeAndVectorPointsAtAngle) {
    for (int16_t amp : {0, 1, 1000, 16384, 32767}) {
        for (uint32_t ang = 0; ang < 65536; ang += 256) {
            uint16_t d[3];
            cmt_phases(static_cast<uint16_t>(ang), amp, d);
            for (int k = 0; k < 3; k++) {
                ASSERT_LE(d[k], CMT_PWM_TOP);
            }
            if (amp < 16384) continue;  // small vectors: quantized to a few counts
            double mag, a;
            vector_of(d, &mag, &a);
            double want = 2 * M_PI * ang / 65536.0;
            double err = remainder(a - want, 2 * M_PI);
            ASSERT_LT(fabs(err), 0.03) << "angle " << ang << " amp " << amp;
            ASSERT_NEAR(mag, amp * 460.0 / 32768.0, 4.0);
        }
    }
}

TEST(Cmt, FullAmplitudeUsesWholeRange) {
    uint16_t lo = 800, hi = 0;
    for (uint32_t ang = 0; ang < 65536; ang += 64) {
        uint16_t d[3];
        cmt_phases(static_cast<uint16_t>(ang), 32767, d);
        for (int k = 0; k < 3; k++) {
            if (d[k] < lo) lo = d[k];
            if (d[k] > hi) hi = d[k];
        }
    }
    EXPECT_LE(lo, 5);
    EXPECT_GE(hi, 794);
}

TEST(Cmt, NegativeAmplitudeIsZero) {
    uint16_t d[3];
    cmt_phases(1234, -5, d);
    EXPECT_EQ(d[0], 400);
    EXPECT_EQ(d[1], 400);
    EXPECT_EQ(d[2], 400);
}

TEST(Cmt, PhaseIncrementMatchesExact) {
    for (int32_t v : {-400000, -74870, -1, 0, 1, 1000, 74870, 314159, 400000}) {
        for (uint8_t pp : {1, 7}) {
            double exact = static_cast<double>(v) * pp * 4294967296.0 / (2 * M_PI * 1e6);
            ASSERT_NEAR(cmt_phase_inc(v, pp), exact, 1.0 + 3e-6 * fabs(exact)) << v;
        }
    }
}

TEST(Cmt, PhaseIncrementClampsAtAliasingLimit) {
    int32_t top = cmt_phase_inc(400000, 40);  // 1.6e7 electrical mrad/s: clamped, no overflow
    EXPECT_EQ(top, cmt_phase_inc(CMT_MAX_ELEC_MRAD_S, 1));
    EXPECT_EQ(cmt_phase_inc(-400000, 40), -top);
    EXPECT_GT(top, 0);
}

// Exact lead angle (one-turn units, not wrapped) for a speed in q8 (1/256 encoder count per 1 ms
// tick), with the aliasing clamp of cmt_phase_inc.
static double exact_lead(double speed_q8, int pp, int lead_q8) {
    const double mrad_per_q8 = 2.0 * M_PI / 16384.0 * 1e6 / 256.0;
    double es = speed_q8 * mrad_per_q8 * pp;
    if (es > CMT_MAX_ELEC_MRAD_S) es = CMT_MAX_ELEC_MRAD_S;
    if (es < -CMT_MAX_ELEC_MRAD_S) es = -CMT_MAX_ELEC_MRAD_S;
    return es * 65536.0 / (2 * M_PI * 1e6) * lead_q8 / 256.0;
}

TEST(Cmt, LeadAngleMatchesExactOverSpeedsAndExtremes) {
    for (int pp : {1, 7, 14, 40}) {
        for (int lead_q8 : {0, 1, 128, 256, 512}) {
            cmt_lead l;
            cmt_lead_init(&l, static_cast<uint8_t>(pp), static_cast<uint16_t>(lead_q8));
            ASSERT_EQ(l.k, pp * lead_q8);
            // q8 speeds up to the estimator's +-2^21 (8192 counts per tick).
            for (int32_t v : {0, 1, -1, 63, 64, -64, -65, 49979, -49979, 104858, 267017, -267017,
                              1000000, -1000000, (1 << 21) - 1, -(1 << 21)}) {
                double want = exact_lead(v, pp, lead_q8);
                // Speed truncated to a quarter count (k/256), product floored (1), the clamp level
                // from a rounded conversion (a quarter of k/256 more), 1e-5 relative.
                double tol = 1.25 * l.k / 256.0 + 1.0 + 1e-5 * fabs(want);
                double got = cmt_lead_angle(&l, v);
                double err = remainder(got - want, 65536.0);  // the angle is taken modulo a turn
                ASSERT_LE(fabs(err), tol) << "pp " << pp << " lead " << lead_q8 << " v " << v;
            }
        }
    }
}

TEST(Cmt, LeadAngleDefaultsWithinFiveUnits) {
    // 7 pole pairs, lead 128/256 tick: k = 896, error below 896/256 + 1 = 4.5 units.
    cmt_lead l;
    cmt_lead_init(&l, 7, 128);
    for (int32_t v = -104858; v <= 104858; v += 97) {  // up to the default SPEED_MAX, 1500 rpm
        double err = remainder(cmt_lead_angle(&l, v) - exact_lead(v, 7, 128), 65536.0);
        ASSERT_LE(fabs(err), 4.5) << v;
    }
}

// The step's commutation: the vector 90 degrees electrical ahead of the rotor (lead included) for
// a positive drive, behind it for a negative one, with |drive| as amplitude; -32768 is no drive.
TEST(Cmt, DrivePutsVectorAheadOrBehindTheRotor) {
    cmt_lead l;
    cmt_lead_init(&l, 7, 128);
    for (int32_t speed_q8 : {0L, 49979L, -49979L, 2097151L, -2097152L}) {
        for (uint16_t mech : {0u, 1u, 5000u, 0x3FFFu, 0xFFFFu}) {
            const uint16_t rotor =
                static_cast<uint16_t>(cmt_elec_angle(mech, 7, 1234) + cmt_lead_angle(&l, speed_q8));
            for (int16_t drive : {0, 1, 20000, 32767, -1, -20000, -32767}) {
                uint16_t d[3], want[3];
                cmt_drive_c(mech, speed_q8, drive, 1234, &l, d);
                const bool pos = drive >= 0;
                cmt_phases(static_cast<uint16_t>(pos ? rotor + 0x4000u : rotor - 0x4000u),
                           static_cast<int16_t>(pos ? drive : -drive), want);
                for (int k = 0; k < 3; k++) ASSERT_EQ(d[k], want[k]) << speed_q8 << " " << drive;
                if (drive != 20000) continue;
                double mag, a;
                vector_of(d, &mag, &a);
                const double err = remainder(a - 2 * M_PI * (rotor + 16384.0) / 65536.0, 2 * M_PI);
                ASSERT_LT(fabs(err), 0.03);
            }
        }
    }
    uint16_t d[3];
    cmt_drive_c(100, 0, -32768, 0, &l, d);
    EXPECT_EQ(d[0], 400);
    EXPECT_EQ(d[1], 400);
    EXPECT_EQ(d[2], 400);
}
