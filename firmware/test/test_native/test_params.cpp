// Parameter store: table sanity, EEPROM image checks, non-blocking save, two slots with a power
// cut at every byte of a save.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "crc16.h"
#include "params.h"
#include "proto.h"
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
    // Saving the same values again goes to the other slot; once both slots hold them, a save
    // writes only the bytes that differ: the sequence number and the CRC (update semantics).
    for (int k = 0; k < 2; k++) {
        int w = FakeEeprom::writes;
        prm_save_begin(&t);
        while (!prm_save_poll(&t)) {
        }
        if (k == 1) {
            EXPECT_LE(FakeEeprom::writes - w, 4);
        }
    }
    FakeEeprom::busy_polls = 0;
}

// An EEPROM image of the defaults with one value set directly (bypassing prm_set's range check,
// as a corrupted or hand-made image would), saved as sequence number `seq`.
static void image_with(uint8_t param, int32_t value, uint16_t seq, uint8_t* image) {
    prm_store s;
    prm_defaults(&s);
    s.v[param] = value;
    prm_image_build(&s, seq, image);
}

// A boot's read of `image` into a store that starts from the defaults.
static bool parse_over_defaults(const uint8_t* image, prm_store* s, uint16_t* seq) {
    prm_defaults(s);
    return prm_image_parse(s, image, seq);
}

TEST(Prm, CorruptImagesRejected) {
    uint8_t good[PRM_IMAGE_SIZE];
    image_with(PRM_KI, 77, 513, good);
    prm_store t;
    uint16_t seq = 0;
    ASSERT_TRUE(parse_over_defaults(good, &t, &seq));
    EXPECT_EQ(t.v[PRM_KI], 77);
    EXPECT_EQ(seq, 513);
    for (int i = 0; i < PRM_IMAGE_SIZE; i++) {  // any flipped byte (magic, version, count,
        uint8_t bad[PRM_IMAGE_SIZE];            // value or CRC) is caught
        for (int k = 0; k < PRM_IMAGE_SIZE; k++) bad[k] = good[k];
        bad[i] ^= 0x10;
        prm_store u;
        EXPECT_FALSE(parse_over_defaults(bad, &u, &seq)) << "byte " << i;
        EXPECT_EQ(u.v[PRM_KI], prm_default(PRM_KI));
    }
}

TEST(Prm, ValidCrcButValueOutOfRangeRejected) {
    uint8_t img[PRM_IMAGE_SIZE];
    image_with(PRM_POLE_PAIRS, 99, 1, img);
    prm_store t;
    uint16_t seq = 0;
    EXPECT_FALSE(parse_over_defaults(img, &t, &seq));
    EXPECT_EQ(t.v[PRM_POLE_PAIRS], 7);
}

// ---- Two slots: which set a boot loads after saves and after a power cut inside a save.

// An EEPROM that loses power at a chosen write: writes before it land, the write at the cut is
// torn (the byte keeps its old value, reads erased 0xFF, or holds garbage), later ones are lost.
namespace {
enum Torn { TORN_KEEP, TORN_ERASED, TORN_GARBAGE };
uint8_t g_mem[4096];
long g_writes;
long g_cut = -1;  // index of the write that the power cut hits; -1: none
Torn g_torn = TORN_KEEP;
uint8_t ee_read(uint16_t a) {
    return g_mem[a];
}
bool ee_ready() {
    return true;
}
void ee_write(uint16_t a, uint8_t v) {
    const long n = g_writes++;
    if (g_cut < 0 || n < g_cut) {
        g_mem[a] = v;
    } else if (n == g_cut) {
        g_mem[a] = g_torn == TORN_KEEP ? g_mem[a] : g_torn == TORN_ERASED ? 0xFF : v ^ 0xA5;
    }
}
const prm_eeprom_if g_iface = {ee_read, ee_ready, ee_write};

struct Set {
    int32_t v[PRM_COUNT];
    bool operator==(const Set& o) const {
        for (int i = 0; i < PRM_COUNT; i++) {
            if (v[i] != o.v[i]) return false;
        }
        return true;
    }
};

Set set_of(const prm_store& s) {
    Set r;
    for (int i = 0; i < PRM_COUNT; i++) r.v[i] = s.v[i];
    return r;
}

Set defaults_set() {
    prm_store s;
    prm_defaults(&s);
    return set_of(s);
}

// A parameter set with every value random within its range (most bytes differ between two).
Set random_set(std::mt19937& rng) {
    Set r;
    for (uint8_t i = 0; i < PRM_COUNT; i++) {
        int32_t v;
        do {
            v = static_cast<int32_t>(rng() % 400001);
        } while (!prm_in_range(i, v));
        r.v[i] = v;
    }
    return r;
}

// Boot, set the values, save to completion (no cut). Returns the number of bytes written.
long save(const Set& want) {
    prm_store s;
    prm_init(&s, &g_iface);
    for (uint8_t i = 0; i < PRM_COUNT; i++) EXPECT_EQ(prm_set(&s, i, want.v[i]), PRM_OK);
    const long before = g_writes;
    prm_save_begin(&s);
    int polls = 0;
    while (!prm_save_poll(&s) && ++polls < 1000) {
    }
    EXPECT_FALSE(s.saving);
    return g_writes - before;
}

// Boot and report what was loaded.
Set boot(bool* ok) {
    prm_store s;
    *ok = prm_init(&s, &g_iface);
    return set_of(s);
}
}  // namespace

TEST(PrmSlots, SavesAlternateSlotsAndTheNewestLoads) {
    std::memset(g_mem, 0xFF, sizeof g_mem);
    g_cut = -1;
    std::mt19937 rng(3);
    for (int k = 0; k < 6; k++) {
        const Set want = random_set(rng);
        save(want);
        bool ok = false;
        EXPECT_TRUE(boot(&ok) == want) << "save " << k;
        EXPECT_TRUE(ok);
        // Slot k % 2 holds this save, sequence k + 1.
        const uint16_t base = PRM_SLOT_ADDR(k % 2);
        EXPECT_EQ(g_mem[base + 2], PRM_LAYOUT_VERSION);
        EXPECT_EQ(g_mem[base + 4] | (g_mem[base + 5] << 8), k + 1);
    }
}

TEST(PrmSlots, SequenceNumberWrapsInSerialOrder) {
    std::memset(g_mem, 0xFF, sizeof g_mem);
    g_cut = -1;
    std::mt19937 rng(4);
    const Set a = random_set(rng);
    const Set b = random_set(rng);
    prm_store s;
    for (int i = 0; i < PRM_COUNT; i++) s.v[i] = a.v[i];
    uint8_t img[PRM_IMAGE_SIZE];
    prm_image_build(&s, 0xFFFF, img);
    for (int i = 0; i < PRM_IMAGE_SIZE; i++) g_mem[PRM_SLOT_ADDR(0) + i] = img[i];
    for (int i = 0; i < PRM_COUNT; i++) s.v[i] = b.v[i];
    prm_image_build(&s, 0x0000, img);  // one after 0xFFFF
    for (int i = 0; i < PRM_IMAGE_SIZE; i++) g_mem[PRM_SLOT_ADDR(1) + i] = img[i];
    bool ok = false;
    EXPECT_TRUE(boot(&ok) == b);
    EXPECT_TRUE(ok);
}

// An image written by earlier firmware: layout version, PRM_MIN_COUNT values (up to ENC_OFFSET_M3),
// sequence number or not. Written at slot 0; returns the set it holds with the later parameters at
// their defaults.
Set write_earlier_image(std::mt19937& rng, uint8_t version) {
    std::memset(g_mem, 0xFF, sizeof g_mem);
    Set old = random_set(rng);
    const int header = version == PRM_LEGACY_VERSION ? PRM_LEGACY_HEADER_SIZE : PRM_HEADER_SIZE;
    uint8_t img[PRM_HEADER_SIZE + 4 * PRM_MIN_COUNT + 2] = {'G', 'W', version, PRM_MIN_COUNT};
    if (header == PRM_HEADER_SIZE) proto_put_u16(&img[4], 7);
    for (int i = 0; i < PRM_MIN_COUNT; i++) proto_put_i32(&img[header + 4 * i], old.v[i]);
    const uint8_t body = static_cast<uint8_t>(header + 4 * PRM_MIN_COUNT);
    proto_put_u16(&img[body], crc16_ccitt(img, body));
    for (int i = 0; i < body + 2; i++) g_mem[i] = img[i];
    for (int i = PRM_MIN_COUNT; i < PRM_COUNT; i++) old.v[i] = prm_default(static_cast<uint8_t>(i));
    return old;
}

TEST(PrmSlots, EarlierImagesLoadWithTheNewParametersAtDefaultsAndAreKeptUntilReplaced) {
    g_cut = -1;
    std::mt19937 rng(5);
    for (uint8_t version : {PRM_LEGACY_VERSION, PRM_LAYOUT_VERSION}) {
        const Set old = write_earlier_image(rng, version);
        bool ok = false;
        EXPECT_TRUE(boot(&ok) == old) << int(version);  // the calibrated offsets kept
        EXPECT_TRUE(ok);
        const Set next = random_set(rng);
        save(next);  // goes to slot 1: the earlier image stays as the previous set
        EXPECT_EQ(g_mem[0], 'G');
        EXPECT_EQ(g_mem[2], version);
        EXPECT_TRUE(boot(&ok) == next);
    }
}

// The acceptance test of the two slots: a save interrupted at every one of its writes, with the
// interrupted byte kept, erased or garbage, leaves the set loaded before it or the new one (the
// new one only once its last byte is written), never the defaults; across several consecutive
// saves, so that both the blank slot and a slot with an older image are overwritten.
TEST(PrmSlots, PowerCutAtEveryByteOfASaveLoadsThePreviousOrTheNewSet) {
    std::mt19937 rng(7);
    const Set defaults = defaults_set();
    for (int start = 0; start < 2; start++) {  // from blank EEPROM, or from a layout-2 image
        std::memset(g_mem, 0xFF, sizeof g_mem);
        g_cut = -1;
        g_writes = 0;
        Set previous = defaults;
        bool have_previous = false;
        if (start == 1) {
            previous = random_set(rng);
            prm_store s;
            for (int i = 0; i < PRM_COUNT; i++) s.v[i] = previous.v[i];
            uint8_t img[PRM_IMAGE_SIZE];
            prm_image_build(&s, 0, img);
            // Rewrite as layout 2 (drop the sequence number, CRC over the shorter body).
            uint8_t legacy[PRM_IMAGE_SIZE];
            legacy[0] = 'G';
            legacy[1] = 'W';
            legacy[2] = PRM_LEGACY_VERSION;
            legacy[3] = PRM_COUNT;
            for (int i = 0; i < 4 * PRM_COUNT; i++) legacy[4 + i] = img[PRM_HEADER_SIZE + i];
            const uint8_t body = PRM_LEGACY_HEADER_SIZE + 4 * PRM_COUNT;
            proto_put_u16(&legacy[body], crc16_ccitt(legacy, body));
            for (int i = 0; i < body + 2; i++) g_mem[i] = legacy[i];
            have_previous = true;
        }
        for (int round = 0; round < 5; round++) {
            const Set next = random_set(rng);
            uint8_t before[sizeof g_mem];
            std::memcpy(before, g_mem, sizeof g_mem);
            // Count the writes of the uninterrupted save.
            g_cut = -1;
            g_writes = 0;
            const long total = save(next);
            ASSERT_GE(total, 3);  // at least the sequence number and the CRC change
            uint8_t after[sizeof g_mem];
            std::memcpy(after, g_mem, sizeof g_mem);
            for (long cut = 0; cut < total; cut++) {
                for (int torn = TORN_KEEP; torn <= TORN_GARBAGE; torn++) {
                    std::memcpy(g_mem, before, sizeof g_mem);
                    g_writes = 0;
                    g_cut = cut;
                    g_torn = static_cast<Torn>(torn);
                    save(next);  // runs to its end; writes from the cut on are lost
                    g_cut = -1;
                    bool ok = false;
                    const Set got = boot(&ok);
                    const bool is_prev = got == previous;
                    const bool is_next = got == next;
                    ASSERT_TRUE(is_prev || is_next)
                        << "start " << start << " round " << round << " cut " << cut;
                    ASSERT_EQ(ok, have_previous || is_next) << "defaults reported";
                    // The last write completes the image: before it, the new set cannot load.
                    if (cut < total - 1) {
                        ASSERT_TRUE(is_prev) << "cut " << cut;
                    }
                }
            }
            std::memcpy(g_mem, after, sizeof g_mem);
            bool ok = false;
            ASSERT_TRUE(boot(&ok) == next);
            previous = next;
            have_previous = true;
        }
    }
}
