// Commutation: waveform table, electrical angle wrap, duties against an ideal SVPWM computed here
// in double precision, duty range, space-vector direction, phase rate, lead.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "commut.h"

// Ideal SVPWM (sine with min-max zero-sequence injection) of a voltage vector at angle phi (rad)
// with a phase amplitude of amp counts: the three duties, centred on 400.
static void ideal_svpwm(double phi, double amp, double out[3]) {
    double s[3];
    for (int k = 0; k < 3; k++) s[k] = cos(phi - k * 2 * M_PI / 3);
    const double zs = (*std::max_element(s, s + 3) + *std::min_element(s, s + 3)) / 2;
    for (int k = 0; k < 3; k++) out[k] = 400.0 + amp * (s[k] - zs);
}

// Phase amplitude in counts of a Q15 drive: 459 counts at 32768 (CMT_SVM_SCALE / 2).
static double amp_counts(int32_t amp_q15) {
    return amp_q15 * (CMT_SVM_SCALE / 2.0) / 32768.0;
}

// Tolerance of a duty against the ideal at the exact angle, in PWM counts. The table index is the
// top byte of a phase's angle and the table is sampled at the bin centres, so a phase's angle is
// off by at most half a bin (128 units, 0.70 degrees) plus 1/3 unit (0x5555 for 120 degrees); the
// injected waveform's steepest slope is 1.5 (where the phase is the middle one, 1.5 * sine), so at
// most 459 * 1.5 * 128.34 * 2 * pi / 65536 = 8.47 counts at full drive. Plus the table's rounding
// (0.5 of 918 per 65536 of amplitude: 0.25 counts) and the floor of the product (1 count).
static double tol_exact(int32_t amp_q15) {
    return std::abs(amp_counts(amp_q15)) * 1.5 * 128.34 * 2 * M_PI / 65536.0 + 1.25;
}
// Against the ideal at the angle the phase's table entry stands for (its bin centre): rounding and
// floor only.
static const double kTolCentre = 1.25;

TEST(Cmt, TableIsTheInjectedWaveform) {
    for (int i = 0; i < CMT_TABLE_SIZE; i++) {
        // Phase a of a unit vector 90 degrees ahead of a rotor at the bin centre.
        const double t = 2 * M_PI * (i + 0.5) / 256;
        double d[3];
        ideal_svpwm(t + M_PI / 2, 1.0, d);
        ASSERT_NEAR(cmt_svm(static_cast<uint8_t>(i)), CMT_SVM_SCALE * (d[0] - 400.0), 0.5) << i;
        ASSERT_LE(std::abs(cmt_svm(static_cast<uint8_t>(i))), 795);
        // Odd half-wave symmetry, exactly: cmt_drive turns the vector by negating the amplitude.
        ASSERT_EQ(cmt_svm(static_cast<uint8_t>(i ^ 0x80)), -cmt_svm(static_cast<uint8_t>(i))) << i;
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

static const int16_t kAmps[] = {0, 1, -1, 1000, 16384, 32767, -20000, -32767, -32768};

TEST(Cmt, PhasesMatchIdealSvpwmAtTheirBinCentres) {
    double worst = 0;
    for (int16_t amp : kAmps) {
        for (uint32_t ang = 0; ang < 65536; ang += 61) {
            uint16_t d[3];
            cmt_phases(static_cast<uint16_t>(ang), amp, d);
            // Phase k's entry: top byte of (angle - 90 deg - k * 120 deg); it stands for the bin
            // centre, the ideal phase-a duty of a vector 90 degrees ahead of it.
            for (int k = 0; k < 3; k++) {
                static const uint16_t shift[3] = {0, 0xAAABu, 0x5555u};  // 0, -120, +120 deg
                const uint16_t theta = static_cast<uint16_t>(ang - 0x4000u + shift[k]);
                const double centre = 2 * M_PI * ((theta >> 8) + 0.5) / 256;
                double want[3];
                ideal_svpwm(centre + M_PI / 2, amp_counts(amp), want);
                const double err = d[k] - want[0];
                worst = std::max(worst, std::abs(err));
                // floor: at most 1 below, table rounding 0.25 either way
                ASSERT_GE(err, -kTolCentre) << "angle " << ang << " amp " << amp << " k " << k;
                ASSERT_LE(err, 0.25 + 1e-9) << "angle " << ang << " amp " << amp << " k " << k;
            }
        }
    }
    EXPECT_GT(worst, 0.5);  // the floor shows: the comparison is not vacuous
}

TEST(Cmt, PhasesMatchIdealSvpwmAtTheExactAngle) {
    double worst = 0;
    for (int16_t amp : kAmps) {
        const double tol = tol_exact(amp);
        for (uint32_t ang = 0; ang < 65536; ang += 7) {
            uint16_t d[3];
            cmt_phases(static_cast<uint16_t>(ang), amp, d);
            double want[3];
            ideal_svpwm(2 * M_PI * ang / 65536.0, amp_counts(amp), want);
            for (int k = 0; k < 3; k++) {
                ASSERT_GE(d[k], 2);
                ASSERT_LE(d[k], 797);
                const double err = d[k] - want[k];
                if (amp == 32767) worst = std::max(worst, std::abs(err));
                ASSERT_LE(std::abs(err), tol) << "angle " << ang << " amp " << amp << " k " << k;
            }
        }
    }
    EXPECT_GT(worst, 6.0);  // the quantisation the tolerance is derived from is there
}

TEST(Cmt, VectorPointsAtAngleWithItsAmplitude) {
    for (int16_t amp : {16384, 32767, -32768}) {
        for (uint32_t ang = 0; ang < 65536; ang += 256) {
            uint16_t d[3];
            cmt_phases(static_cast<uint16_t>(ang), amp, d);
            double mag, a;
            vector_of(d, &mag, &a);
            // A negative amplitude points the vector the other way.
            const double want = 2 * M_PI * ang / 65536.0 + (amp < 0 ? M_PI : 0.0);
            ASSERT_LT(std::abs(remainder(a - want, 2 * M_PI)), 0.03) << "angle " << ang;
            ASSERT_NEAR(mag, std::abs(amp_counts(amp)), 4.0) << "angle " << ang;
        }
    }
}

TEST(Cmt, LineToLineAmplitudeAndCentre) {
    for (int16_t amp : {4000, 16384, 32767, -32768}) {
        double ll_max = -1000, ll_min = 1000, sum[3] = {0, 0, 0};
        int n = 0;
        for (uint32_t ang = 0; ang < 65536; ang += 16) {
            uint16_t d[3];
            cmt_phases(static_cast<uint16_t>(ang), amp, d);
            ll_max = std::max(ll_max, static_cast<double>(d[0]) - d[1]);
            ll_min = std::min(ll_min, static_cast<double>(d[0]) - d[1]);
            // min-max injection centres the highest and the lowest duty on 400
            const uint16_t hi = std::max({d[0], d[1], d[2]}), lo = std::min({d[0], d[1], d[2]});
            ASSERT_NEAR((hi + lo) / 2.0, 400.0, 2 * tol_exact(amp)) << ang;
            for (int k = 0; k < 3; k++) sum[k] += d[k];
            n++;
        }
        // sqrt(3) * 459 counts at full drive: 795 of the 800 counts of the supply.
        const double want = sqrt(3.0) * std::abs(amp_counts(amp));
        EXPECT_NEAR(ll_max, want, 3.0) << amp;
        EXPECT_NEAR(-ll_min, want, 3.0) << amp;
        for (int k = 0; k < 3; k++) EXPECT_NEAR(sum[k] / n, 400.0, 1.0) << amp;
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

TEST(Cmt, ZeroAndNegativeAmplitude) {
    uint16_t d[3], e[3];
    cmt_phases(1234, 0, d);
    EXPECT_EQ(d[0], 400);
    EXPECT_EQ(d[1], 400);
    EXPECT_EQ(d[2], 400);
    // A negative amplitude is the vector turned by 180 degrees, exactly.
    for (int16_t amp : {1, 5, 20000, 32767}) {
        for (uint32_t ang = 0; ang < 65536; ang += 97) {
            cmt_phases(static_cast<uint16_t>(ang), static_cast<int16_t>(-amp), d);
            cmt_phases(static_cast<uint16_t>(ang + 0x8000u), amp, e);
            for (int k = 0; k < 3; k++) ASSERT_EQ(d[k], e[k]) << ang << " " << amp;
        }
    }
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
// a positive drive, behind it for a negative one, with |drive| as amplitude (-32768: full
// amplitude behind), against the ideal SVPWM.
TEST(Cmt, DrivePutsVectorAheadOrBehindTheRotor) {
    for (int pp : {1, 7, 40}) {
        cmt_lead l;
        cmt_lead_init(&l, static_cast<uint8_t>(pp), 128);
        for (int32_t speed_q8 : {0L, 49979L, -49979L, 2097151L, -2097152L}) {
            for (uint16_t mech : {0u, 1u, 5000u, 0x3FFFu, 0xFFFFu}) {
                const uint16_t rotor = static_cast<uint16_t>(
                    cmt_elec_angle(mech, l.pole_pairs, 1234) + cmt_lead_angle(&l, speed_q8));
                for (int16_t drive : {0, 1, 20000, 32767, -1, -20000, -32767, -32768}) {
                    uint16_t d[3], want[3];
                    cmt_drive(mech, speed_q8, drive, 1234, &l, d);
                    const bool pos = drive >= 0;
                    const int32_t mag = pos ? drive : -static_cast<int32_t>(drive);
                    if (mag <= 32767) {  // the same as cmt_phases 90 degrees ahead / behind
                        cmt_phases(static_cast<uint16_t>(pos ? rotor + 0x4000u : rotor - 0x4000u),
                                   static_cast<int16_t>(mag), want);
                        for (int k = 0; k < 3; k++)
                            ASSERT_EQ(d[k], want[k]) << speed_q8 << " " << drive;
                    }
                    double ideal[3];
                    const double phi = 2 * M_PI * rotor / 65536.0 + (pos ? M_PI / 2 : -M_PI / 2);
                    ideal_svpwm(phi, amp_counts(mag), ideal);
                    for (int k = 0; k < 3; k++) {
                        ASSERT_LE(std::abs(d[k] - ideal[k]), tol_exact(mag)) << drive << " " << k;
                        ASSERT_LE(d[k], CMT_PWM_TOP);
                    }
                    if (mag < 20000) continue;
                    double m, a;
                    vector_of(d, &m, &a);
                    ASSERT_LT(std::abs(remainder(a - phi, 2 * M_PI)), 0.03);
                }
            }
        }
    }
    cmt_lead l;
    cmt_lead_init(&l, 7, 128);
    uint16_t d[3], e[3];
    cmt_drive(100, 0, 0, 0, &l, d);
    EXPECT_EQ(d[0], 400);
    EXPECT_EQ(d[1], 400);
    EXPECT_EQ(d[2], 400);
    // -32768 is the full amplitude behind the rotor: within a count of -32767.
    cmt_drive(100, 0, -32768, 0, &l, d);
    cmt_drive(100, 0, -32767, 0, &l, e);
    for (int k = 0; k < 3; k++) {
        EXPECT_NE(d[k], 400);
        EXPECT_LE(std::abs(d[k] - e[k]), 1);
    }
}
