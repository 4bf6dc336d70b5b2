// Framing: CRC-16, COBS, frame round trips and every corrupt-frame case.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "cobs.h"
#include "crc16.h"
#include "proto.h"

using Bytes = std::vector<uint8_t>;

TEST(Crc16, CheckValue) {
    const uint8_t s[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    EXPECT_EQ(crc16_ccitt(s, 9), 0x29B1);
    EXPECT_EQ(crc16_ccitt(s, 0), 0xFFFF);
}

// Bit-by-bit CRC-16/CCITT-FALSE: the definition the table-driven crc16_ccitt must reproduce.
static uint16_t crc16_bitwise(const uint8_t* p, size_t len) {
    uint16_t crc = 0xFFFF;
    for (size_t i = 0; i < len; i++) {
        crc ^= static_cast<uint16_t>(p[i] << 8);
        for (int b = 0; b < 8; b++) {
            crc = (crc & 0x8000) ? static_cast<uint16_t>((crc << 1) ^ 0x1021)
                                 : static_cast<uint16_t>(crc << 1);
        }
    }
    return crc;
}

TEST(Crc16, TableIsTheBitwiseRemainder) {
    for (int i = 0; i < 256; i++) {
        uint16_t r = static_cast<uint16_t>(i << 8);
        for (int b = 0; b < 8; b++) {
            r = (r & 0x8000) ? static_cast<uint16_t>((r << 1) ^ 0x1021)
                             : static_cast<uint16_t>(r << 1);
        }
        ASSERT_EQ(crc16_table[0][i], r >> 8) << i;
        ASSERT_EQ(crc16_table[1][i], r & 0xFF) << i;
    }
}

TEST(Crc16, MatchesBitwiseReference) {
    std::mt19937 rng(1);
    for (int n = 0; n < 50000; n++) {
        uint8_t buf[255];
        uint8_t len = static_cast<uint8_t>(n < 256 ? n : rng() % 256);
        const int kind = n % 8;  // mostly random bytes, some all-zero and all-0xFF buffers
        for (uint8_t i = 0; i < len; i++) {
            buf[i] = kind == 0 ? 0 : kind == 1 ? 0xFF : static_cast<uint8_t>(rng());
        }
        const uint16_t ref = crc16_bitwise(buf, len);
        ASSERT_EQ(crc16_ccitt(buf, len), ref) << "n=" << n << " len=" << int(len);
        uint16_t one = CRC16_INIT;
        for (uint8_t i = 0; i < len; i++) one = crc16_update(one, buf[i]);
        ASSERT_EQ(one, ref) << "n=" << n;
    }
}

static Bytes cobs_rt(const Bytes& in) {
    uint8_t enc[300], dec[300];
    uint8_t n = cobs_encode(in.data(), static_cast<uint8_t>(in.size()), enc);
    EXPECT_EQ(n, in.size() + 1);
    for (uint8_t i = 0; i < n; i++) EXPECT_NE(enc[i], 0);
    int16_t m = cobs_decode(enc, n, dec);
    EXPECT_GE(m, 0);
    return Bytes(dec, dec + (m < 0 ? 0 : m));
}

TEST(Cobs, KnownVectors) {
    uint8_t out[8];
    const uint8_t a[] = {0x00};
    ASSERT_EQ(cobs_encode(a, 1, out), 2);
    EXPECT_EQ(out[0], 1);
    EXPECT_EQ(out[1], 1);
    const uint8_t b[] = {0x11, 0x22, 0x00, 0x33};
    ASSERT_EQ(cobs_encode(b, 4, out), 5);
    const uint8_t want[] = {0x03, 0x11, 0x22, 0x02, 0x33};
    EXPECT_EQ(memcmp(out, want, 5), 0);
}

TEST(Cobs, RoundTripsRandomAndZeroHeavy) {
    std::mt19937 rng(2);
    for (int n = 0; n < 500; n++) {
        Bytes in(rng() % 254);
        for (auto& x : in) x = (rng() % 3 == 0) ? 0 : static_cast<uint8_t>(rng());
        ASSERT_EQ(cobs_rt(in), in);
    }
    ASSERT_EQ(cobs_rt(Bytes(253, 0)), Bytes(253, 0));
    ASSERT_EQ(cobs_rt(Bytes(253, 7)), Bytes(253, 7));
    ASSERT_EQ(cobs_rt(Bytes()), Bytes());
}

TEST(Cobs, InvalidInputRejected) {
    uint8_t out[16];
    const uint8_t zero_inside[] = {0x03, 0x11, 0x00};
    EXPECT_EQ(cobs_decode(zero_inside, 3, out), -1);
    const uint8_t past_end[] = {0x05, 0x11, 0x22};
    EXPECT_EQ(cobs_decode(past_end, 3, out), -1);
    const uint8_t zero_code[] = {0x00};
    EXPECT_EQ(cobs_decode(zero_code, 1, out), -1);
}

// Feed bytes, return the last non-NONE result (and the frame).
static proto_rx_result feed(proto_rx* rx, const Bytes& wire, proto_frame* f) {
    proto_rx_result last = PROTO_RX_NONE;
    for (uint8_t b : wire) {
        proto_rx_result r = proto_rx_push(rx, b, f);
        if (r != PROTO_RX_NONE) last = r;
    }
    return last;
}

static Bytes build(uint8_t id, const Bytes& payload) {
    uint8_t out[PROTO_MAX_WIRE];
    uint8_t n = proto_build(id, payload.data(), static_cast<uint8_t>(payload.size()), out);
    return Bytes(out, out + n);
}

// Raw (un-COBSed) body with a correct CRC, then framed: lets tests corrupt any layer.
static Bytes frame_raw(Bytes raw, bool add_crc = true) {
    if (add_crc) {
        uint16_t c = crc16_ccitt(raw.data(), static_cast<uint8_t>(raw.size()));
        raw.push_back(static_cast<uint8_t>(c));
        raw.push_back(static_cast<uint8_t>(c >> 8));
    }
    Bytes enc(raw.size() + 2);
    uint8_t n = cobs_encode(raw.data(), static_cast<uint8_t>(raw.size()), enc.data());
    enc.resize(n);
    enc.push_back(0);
    return enc;
}

TEST(Proto, EveryMessageRoundTrips) {
    std::mt19937 rng(3);
    const uint8_t ids[] = {
#define PROTO_MSG(name, id, dir, len, fmt, fields) id,
#include "proto_messages.def"
#undef PROTO_MSG
    };
    for (uint8_t id : ids) {
        for (int rep = 0; rep < 20; rep++) {
            Bytes p(static_cast<size_t>(proto_payload_len(id)));
            for (auto& x : p) x = (rng() % 4 == 0) ? 0 : static_cast<uint8_t>(rng());
            proto_rx rx;
            proto_rx_init(&rx);
            proto_frame f;
            Bytes wire = build(id, p);
            ASSERT_LE(wire.size(), static_cast<size_t>(PROTO_MAX_WIRE));
            ASSERT_EQ(feed(&rx, wire, &f), PROTO_RX_FRAME);
            ASSERT_EQ(f.id, id);
            ASSERT_EQ(Bytes(f.payload, f.payload + f.len), p);
        }
    }
}

TEST(Proto, BackToBackFramesAndEmptyFramesIgnored) {
    proto_rx rx;
    proto_rx_init(&rx);
    proto_frame f;
    Bytes wire = {0, 0};
    Bytes a = build(PROTO_ID_HEARTBEAT, {});
    wire.insert(wire.end(), a.begin(), a.end());
    wire.insert(wire.end(), a.begin(), a.end());
    int frames = 0;
    for (uint8_t b : wire) frames += proto_rx_push(&rx, b, &f) == PROTO_RX_FRAME;
    EXPECT_EQ(frames, 2);
}

TEST(Proto, BadCrc) {
    proto_rx rx;
    proto_rx_init(&rx);
    proto_frame f;
    Bytes raw = {PROTO_ID_PARAM_GET, 3, 0x12, 0x34};  // wrong CRC bytes
    EXPECT_EQ(feed(&rx, frame_raw(raw, false), &f), PROTO_RX_BAD_CRC);
    // Every single-bit flip of a good frame's body is caught.
    Bytes body = {PROTO_ID_PARAM_SET, 4, 1, 2, 3, 4};
    for (size_t i = 0; i < body.size() * 8; i++) {
        Bytes good = frame_raw(body);
        Bytes dec(good.size());
        int16_t n = cobs_decode(good.data(), static_cast<uint8_t>(good.size() - 1), dec.data());
        dec.resize(static_cast<size_t>(n));
        dec[i / 8] ^= static_cast<uint8_t>(1u << (i % 8));
        EXPECT_EQ(feed(&rx, frame_raw(dec, false), &f), PROTO_RX_BAD_CRC) << "bit " << i;
    }
}

TEST(Proto, ShortFrames) {
    proto_rx rx;
    proto_rx_init(&rx);
    proto_frame f;
    EXPECT_EQ(feed(&rx, frame_raw({0x01}, false), &f), PROTO_RX_SHORT);
    EXPECT_EQ(feed(&rx, frame_raw({0x01, 0x02}, false), &f), PROTO_RX_SHORT);
}

TEST(Proto, OversizeFrameDroppedAndNextFrameFine) {
    proto_rx rx;
    proto_rx_init(&rx);
    proto_frame f;
    Bytes junk(200, 0x55);
    junk.push_back(0);
    EXPECT_EQ(feed(&rx, junk, &f), PROTO_RX_OVERSIZE);
    Bytes ok_payload(PROTO_MAX_PAYLOAD, 1);
    Bytes too_long = frame_raw([&] {
        Bytes r = {PROTO_ID_HELLO};
        r.insert(r.end(), ok_payload.begin(), ok_payload.end());
        r.push_back(9);  // one byte above the maximum payload
        return r;
    }());
    EXPECT_EQ(feed(&rx, too_long, &f), PROTO_RX_OVERSIZE);
    EXPECT_EQ(feed(&rx, build(PROTO_ID_HELLO, {}), &f), PROTO_RX_FRAME);
}

TEST(Proto, BadCobs) {
    proto_rx rx;
    proto_rx_init(&rx);
    proto_frame f;
    EXPECT_EQ(feed(&rx, {0x09, 0x01, 0x02, 0x03, 0x00}, &f), PROTO_RX_BAD_COBS);
}

TEST(Proto, UnknownId) {
    proto_rx rx;
    proto_rx_init(&rx);
    proto_frame f;
    EXPECT_EQ(feed(&rx, frame_raw({0x42, 1, 2}), &f), PROTO_RX_UNKNOWN_ID);
    EXPECT_EQ(f.id, 0x42);
    EXPECT_EQ(proto_payload_len(0x42), -1);
    EXPECT_FALSE(proto_to_device(0x42));
    EXPECT_TRUE(proto_to_device(PROTO_ID_SET_SPEEDS));
    EXPECT_FALSE(proto_to_device(PROTO_ID_TELEMETRY));
}

TEST(Proto, WrongLength) {
    proto_rx rx;
    proto_rx_init(&rx);
    proto_frame f;
    EXPECT_EQ(feed(&rx, frame_raw({PROTO_ID_SET_SPEEDS, 1, 2, 3}), &f), PROTO_RX_BAD_LENGTH);
    EXPECT_EQ(f.len, 3);
    EXPECT_EQ(feed(&rx, frame_raw({PROTO_ID_HEARTBEAT, 0}), &f), PROTO_RX_BAD_LENGTH);
}

TEST(Proto, BuildRefusesOversizePayload) {
    uint8_t p[PROTO_MAX_PAYLOAD + 1] = {0};
    uint8_t out[PROTO_MAX_WIRE + 8];
    EXPECT_EQ(proto_build(PROTO_ID_HELLO, p, PROTO_MAX_PAYLOAD + 1, out), 0);
}

TEST(Proto, LittleEndianPacking) {
    uint8_t b[4];
    proto_put_i32(b, -2);
    EXPECT_EQ(b[0], 0xFE);
    EXPECT_EQ(b[3], 0xFF);
    EXPECT_EQ(proto_get_i32(b), -2);
    proto_put_u16(b, 0x1234);
    EXPECT_EQ(b[0], 0x34);
    EXPECT_EQ(proto_get_u16(b), 0x1234);
}

// The board's receive interrupt recognises STOP_ALL by these bytes alone (board_uart.cpp).
TEST(Proto, StopAllWireFrameIsTheBuiltOne) {
    const Bytes wire = PROTO_STOP_ALL_WIRE;
    ASSERT_EQ(wire.size(), static_cast<size_t>(PROTO_STOP_ALL_WIRE_LEN));
    EXPECT_EQ(build(PROTO_ID_STOP_ALL, {}), wire);
}
