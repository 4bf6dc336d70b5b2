// Parameter store: table sanity, EEPROM image checks, non-blocking save.
#include <gtest/gtest.h>

#include "prm.h"
#include "test_support.h"

TEST(Prm, DefaultsInRangeAndOutOfRangeRejected) {
    prm_store s;
    prm_defaults(&s);
    for (uint8_t i = 0; i < PRM_COUNT; i++) EXPECT_TRUE(prm_in_range(i, s.v[i]));
    EXPECT_EQ(prm_set(&s, PRM_POLE_PAIRS, 0), PRM_OUT_OF_RANGE);
    EXPECT_EQ(prm_set(&s, PRM_POLE_PAIRS, 41), PRM_OUT_OF_RANGE);
    EXPECT_EQ(s.v[PRM_POLE_PAIRS], 7);
    EXPECT_EQ(prm_set(&s, PRM_COUNT, 1), PRM_UNKNOWN);
    EXPECT_EQ(prm_set(&s, PRM_SPEED_MAX_MRAD_S, 400000), PRM_OK);
    EXPECT_EQ(prm_set(&s, PRM_SPEED_MAX_MRAD_S, 400001), PRM_OUT_OF_RANGE);
}

TEST(Prm, BlankEepromGivesDefaults) {
    FakeEeprom::erase();
    prm_store s;
    EXPECT_FALSE(prm_init(&s, &FakeEeprom::iface));
    for (uint8_t i = 0; i < PRM_COUNT; i++) EXPECT_EQ(s.v[i], prm_default(i));
}

TEST(Prm, SaveIsNonBlockingAndReloads) {
    FakeEeprom::erase();
    FakeEeprom::busy_polls = 3;
    prm_store s;
    prm_init(&s, &FakeEeprom::iface);
    prm_set(&s, PRM_KP, 1234);
    prm_set(&s, PRM_SPEED_MAX_MRAD_S, 314159);
    prm_save_begin(&s);
    int polls = 0, done = 0;
    while (s.saving && polls < 10000) {
        int before = FakeEeprom::writes;
        done += prm_save_poll(&s);
        EXPECT_LE(FakeEeprom::writes - before, 1);  // at most one byte per poll
        polls++;
    }
    EXPECT_EQ(done, 1);
    EXPECT_GT(polls, PRM_IMAGE_SIZE * 3);  // waited for the busy EEPROM
    prm_store t;
    EXPECT_TRUE(prm_init(&t, &FakeEeprom::iface));
    EXPECT_EQ(t.v[PRM_KP], 1234);
    EXPECT_EQ(t.v[PRM_SPEED_MAX_MRAD_S], 314159);
    // Saving the same values again writes nothing (update semantics).
    int w = FakeEeprom::writes;
    prm_save_begin(&t);
    while (!prm_save_poll(&t)) {
    }
    EXPECT_EQ(FakeEeprom::writes, w);
    FakeEeprom::busy_polls = 0;
}

TEST(Prm, CorruptImagesRejected) {
    prm_store s;
    prm_defaults(&s);
    s.v[PRM_KI] = 77;
    uint8_t good[PRM_IMAGE_SIZE];
    prm_image_build(&s, good);
    prm_store t;
    prm_defaults(&t);
    ASSERT_TRUE(prm_image_parse(&t, good));
    EXPECT_EQ(t.v[PRM_KI], 77);
    for (int i = 0; i < PRM_IMAGE_SIZE; i++) {  // any flipped byte (magic, version, count,
        uint8_t bad[PRM_IMAGE_SIZE];            // value or CRC) is caught
        for (int k = 0; k < PRM_IMAGE_SIZE; k++) bad[k] = good[k];
        bad[i] ^= 0x10;
        prm_store u;
        prm_defaults(&u);
        EXPECT_FALSE(prm_image_parse(&u, bad)) << "byte " << i;
        EXPECT_EQ(u.v[PRM_KI], prm_default(PRM_KI));
    }
}

TEST(Prm, ValidCrcButValueOutOfRangeRejected) {
    prm_store s;
    prm_defaults(&s);
    s.v[PRM_POLE_PAIRS] = 99;  // bypass prm_set
    uint8_t img[PRM_IMAGE_SIZE];
    prm_image_build(&s, img);
    prm_store t;
    prm_defaults(&t);
    EXPECT_FALSE(prm_image_parse(&t, img));
    EXPECT_EQ(t.v[PRM_POLE_PAIRS], 7);
}
