// Widening multiplies of the port header at the extremes of their 16-bit operands.
#include <gtest/gtest.h>

#include <cstdint>

#include "port_progmem.h"

TEST(Port, MulU16Extremes) {
    EXPECT_EQ(port_mul_u16(0, 0xFFFF), 0u);
    EXPECT_EQ(port_mul_u16(1, 0xFFFF), 0xFFFFu);
    EXPECT_EQ(port_mul_u16(0xFFFF, 0xFFFF), 0xFFFE0001u);  // 2^32 - 2^17 + 1: no wrap
    EXPECT_EQ(port_mul_u16(32767, 65535), 2147385345u);
    EXPECT_EQ(port_mul_u16(0x8000, 0x8000), 0x40000000u);
}

TEST(Port, MulS16Extremes) {
    EXPECT_EQ(port_mul_s16(-32768, -32768), 1073741824L);
    EXPECT_EQ(port_mul_s16(-32768, 32767), -1073709056L);
    EXPECT_EQ(port_mul_s16(32767, 32767), 1073676289L);
    EXPECT_EQ(port_mul_s16(-1, 1), -1L);
}

TEST(Port, MulHiS16IsFloorOfProductOver65536) {
    EXPECT_EQ(port_mulhi_s16(-32768, -32768), 16384);
    EXPECT_EQ(port_mulhi_s16(32767, 32767), 16383);
    EXPECT_EQ(port_mulhi_s16(-32768, 32767), -16384);  // -16383.5 rounds down
    EXPECT_EQ(port_mulhi_s16(-1, 1), -1);              // floor, not truncation
    EXPECT_EQ(port_mulhi_s16(1, 1), 0);
    for (int32_t a = -32768; a <= 32767; a += 257) {
        for (int32_t b : {-32768, -1838, -1, 0, 1, 918, 1838, 32767}) {
            int64_t p = static_cast<int64_t>(a) * b;
            int64_t floor_div = p >= 0 ? p / 65536 : -((-p + 65535) / 65536);
            ASSERT_EQ(port_mulhi_s16(static_cast<int16_t>(a), static_cast<int16_t>(b)), floor_div)
                << a << " * " << b;
        }
    }
}

TEST(Port, MulHiU16IsHighWordOfProduct) {
    EXPECT_EQ(port_mulhi_u16(0xFFFF, 0xFFFF), 0xFFFE);
    EXPECT_EQ(port_mulhi_u16(0xFFFF, 1), 0);
    EXPECT_EQ(port_mulhi_u16(0x8000, 2), 1);
    EXPECT_EQ(port_mulhi_u16(43748, 32639), (43748u * 32639u) >> 16);
    for (uint32_t a = 0; a < 65536; a += 251) {
        for (uint32_t b : {0u, 1u, 255u, 256u, 32639u, 43748u, 65535u}) {
            ASSERT_EQ(port_mulhi_u16(static_cast<uint16_t>(a), static_cast<uint16_t>(b)),
                      (a * b) >> 16);
        }
    }
}

TEST(Port, MulS24U8AtTheExtremesOf24Bits) {
    // The speed filter's use: |a| < 2^23 (x - y of two q8 speeds), b = 2^(8 - shift) <= 128.
    const int32_t top = (1 << 23) - 1, bottom = -(1 << 23);
    EXPECT_EQ(port_mul_s24_u8(top, 255), static_cast<int32_t>(int64_t{top} * 255));
    EXPECT_EQ(port_mul_s24_u8(bottom, 255), static_cast<int32_t>(int64_t{bottom} * 255));
    EXPECT_EQ(port_mul_s24_u8(bottom, 128), -(1 << 30));
    EXPECT_EQ(port_mul_s24_u8(-1, 1), -1);
    EXPECT_EQ(port_mul_s24_u8(-1, 0), 0);
    for (int32_t a = bottom; a <= top; a += 65537) {
        for (int b : {0, 1, 2, 64, 127, 128, 255}) {
            ASSERT_EQ(port_mul_s24_u8(a, static_cast<uint8_t>(b)), a * b) << a << " * " << b;
        }
    }
}
