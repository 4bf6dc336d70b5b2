#include "proto.h"

#include "crc16.h"
#include "port_progmem.h"

// Compile-time check that each payload length matches its struct format in the table.
static constexpr uint8_t proto_char_size(char c) {
    return (c == 'B' || c == 'b') ? 1 : (c == 'H' || c == 'h') ? 2 : (c == 'I' || c == 'i') ? 4 : 0;
}
static constexpr uint8_t proto_fmt_size(const char* f) {
    return *f == 0 ? 0 : static_cast<uint8_t>(proto_char_size(*f) + proto_fmt_size(f + 1));
}
#define PROTO_MSG(name, id, dir, len, fmt, fields)                                 \
    static_assert(proto_fmt_size(fmt) == (len), "format/length mismatch: " #name); \
    static_assert((len) <= PROTO_MAX_PAYLOAD, "payload too long: " #name);
#include "proto_messages.def"
#undef PROTO_MSG

// The message table in flash, searched in its order (the host's messages first): a switch over
// the ids compiled into a 134-byte lookup table that avr-gcc keeps in RAM (.data).
struct proto_row {
    uint8_t id, len, to_device;
};
#define PROTO_TO_DEVICE_H2D 1
#define PROTO_TO_DEVICE_D2H 0
static const proto_row proto_rows[] PORT_PROGMEM = {
#define PROTO_MSG(name, id, dir, len, fmt, fields) {id, len, PROTO_TO_DEVICE_##dir},
#include "proto_messages.def"
#undef PROTO_MSG
};
#define PROTO_ROWS (sizeof proto_rows / sizeof proto_rows[0])

// The row of a message id, or PROTO_ROWS.
static uint8_t proto_row_of(uint8_t id) {
    uint8_t i = 0;
    while (i < PROTO_ROWS && PORT_READ_U8(&proto_rows[i].id) != id) i++;
    return i;
}

int16_t proto_payload_len(uint8_t id) {
    const uint8_t i = proto_row_of(id);
    return i < PROTO_ROWS ? PORT_READ_U8(&proto_rows[i].len) : -1;
}

bool proto_to_device(uint8_t id) {
    const uint8_t i = proto_row_of(id);
    return i < PROTO_ROWS && PORT_READ_U8(&proto_rows[i].to_device);
}

void proto_rx_init(proto_rx* rx) {
    rx->n = 0;
    rx->overflow = 0;
}

proto_rx_result proto_rx_end(proto_rx* rx, uint8_t byte) {
    if (byte != 0) {
        rx->overflow = 1;  // past PROTO_MAX_ENCODED: keep discarding until the next delimiter
        return PROTO_RX_NONE;
    }
    const uint8_t overflow = rx->overflow;
    const uint8_t n = rx->n;
    rx->n = 0;
    rx->overflow = 0;
    if (overflow) return PROTO_RX_OVERSIZE;
    if (n == 0) return PROTO_RX_NONE;
    const int16_t decoded = cobs_decode(rx->buf, n, rx->buf);
    if (decoded < 0) return PROTO_RX_BAD_COBS;
    if (decoded < 3) return PROTO_RX_SHORT;
    rx->n = static_cast<uint8_t>(decoded);
    return PROTO_RX_CHECK;
}

proto_rx_result proto_rx_check(proto_rx* rx, proto_frame* out) {
    const uint8_t body = static_cast<uint8_t>(rx->n - 2);
    rx->n = 0;
    if (crc16_ccitt(rx->buf, body) != proto_get_u16(&rx->buf[body])) return PROTO_RX_BAD_CRC;
    out->id = rx->buf[0];
    out->len = static_cast<uint8_t>(body - 1);
    out->payload = &rx->buf[1];
    const int16_t expect = proto_payload_len(out->id);
    if (expect < 0) return PROTO_RX_UNKNOWN_ID;
    if (expect != out->len) return PROTO_RX_BAD_LENGTH;
    return PROTO_RX_FRAME;
}

proto_rx_result proto_rx_push(proto_rx* rx, uint8_t byte, proto_frame* out) {
    if (proto_rx_append(rx, byte)) return PROTO_RX_NONE;
    const proto_rx_result r = proto_rx_end(rx, byte);
    return r == PROTO_RX_CHECK ? proto_rx_check(rx, out) : r;
}

void proto_seal(uint8_t* raw, uint8_t body) {
    proto_put_u16(&raw[body], crc16_ccitt(raw, body));
}

uint8_t proto_wire(const uint8_t* raw, uint8_t raw_len, uint8_t* out) {
    const uint8_t n = cobs_encode(raw, raw_len, out);
    out[n] = 0;
    return static_cast<uint8_t>(n + 1);
}

uint8_t proto_build(uint8_t id, const uint8_t* payload, uint8_t len, uint8_t* out) {
    if (len > PROTO_MAX_PAYLOAD) return 0;
    uint8_t raw[PROTO_MAX_RAW];
    raw[0] = id;
    for (uint8_t i = 0; i < len; i++) raw[1 + i] = payload[i];
    const uint8_t body = static_cast<uint8_t>(len + 1);
    proto_seal(raw, body);
    return proto_wire(raw, static_cast<uint8_t>(body + 2), out);
}

void proto_put_u16(uint8_t* p, uint16_t v) {
    p[0] = static_cast<uint8_t>(v);
    p[1] = static_cast<uint8_t>(v >> 8);
}

void proto_put_u32(uint8_t* p, uint32_t v) {
    proto_put_u16(p, static_cast<uint16_t>(v));
    proto_put_u16(p + 2, static_cast<uint16_t>(v >> 16));
}

uint16_t proto_get_u16(const uint8_t* p) {
    return static_cast<uint16_t>(p[0] | (static_cast<uint16_t>(p[1]) << 8));
}

uint32_t proto_get_u32(const uint8_t* p) {
    return proto_get_u16(p) | (static_cast<uint32_t>(proto_get_u16(p + 2)) << 16);
}
