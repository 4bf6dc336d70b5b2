#include "crc16.h"

uint16_t crc16_update(uint16_t crc, uint8_t byte) {
    uint8_t t = static_cast<uint8_t>((crc >> 8) ^ byte);
    uint8_t hi = static_cast<uint8_t>(crc ^ PORT_READ_U8(&crc16_table[0][t]));
    uint8_t lo = PORT_READ_U8(&crc16_table[1][t]);
    return static_cast<uint16_t>((static_cast<uint16_t>(hi) << 8) | lo);
}

uint16_t crc16_ccitt(const uint8_t* data, uint8_t len) {
#if defined(__AVR__)
    // 16 cycles per byte: the row is selected by ZH, the entry by ZL = t (the table is aligned
    // to 256 bytes, so no address arithmetic). port-check compares it with the bitwise division.
    uint8_t hi = 0xFF;
    uint8_t lo = 0xFF;
    if (len == 0) return CRC16_INIT;
    const uint8_t* z;
    uint8_t t;
    __asm__ volatile(
        "1:\n\t"
        "ld %[t], %a[p]+\n\t"       // 2
        "eor %[t], %[hi]\n\t"       // 1
        "mov r30, %[t]\n\t"         // 1: ZL = t
        "ldi r31, hi8(%[tab])\n\t"  // 1: row 0
        "lpm %[hi], Z\n\t"          // 3
        "eor %[hi], %[lo]\n\t"      // 1: new high = old low ^ table high
        "inc r31\n\t"               // 1: row 1
        "lpm %[lo], Z\n\t"          // 3
        "dec %[n]\n\t"              // 1
        "brne 1b\n\t"               // 2 (1 at the end)
        : [hi] "+r"(hi), [lo] "+r"(lo), [p] "+e"(data), [n] "+r"(len), [t] "=&r"(t), "=z"(z)
        : [tab] "i"(crc16_table)
        : "memory");
    (void)z;
    return static_cast<uint16_t>((static_cast<uint16_t>(hi) << 8) | lo);
#else
    uint16_t crc = CRC16_INIT;
    for (uint8_t i = 0; i < len; i++) crc = crc16_update(crc, data[i]);
    return crc;
#endif
}
