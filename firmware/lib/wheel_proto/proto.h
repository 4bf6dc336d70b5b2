// proto.h - wheel-board frames: message ids from proto_messages.def, framing, byte packing.
//
// Wire frame: COBS( id | payload | crc16 ) 0x00. The CRC-16/CCITT-FALSE covers id and payload
// and is sent low byte first; all multi-byte fields are little-endian. See docs/protocol.md.
#ifndef PROTO_H
#define PROTO_H

#include <stdint.h>

#include "cobs.h"
#include "proto_version.h"

#define PROTO_MAX_PAYLOAD 40
#define PROTO_MAX_RAW (1 + PROTO_MAX_PAYLOAD + 2)
#define PROTO_MAX_ENCODED COBS_ENCODED_SIZE(PROTO_MAX_RAW)
#define PROTO_MAX_WIRE (PROTO_MAX_ENCODED + 1)

enum proto_id : uint8_t {
#define PROTO_MSG(name, id, dir, len, fmt, fields) PROTO_ID_##name = id,
#include "proto_messages.def"
#undef PROTO_MSG
};

enum proto_len : uint8_t {
#define PROTO_MSG(name, id, dir, len, fmt, fields) PROTO_LEN_##name = len,
#include "proto_messages.def"
#undef PROTO_MSG
};

enum proto_fault_bit : uint16_t {
#define PROTO_FAULT(name, bit, text) PROTO_FAULT_##name = 1u << bit,
#include "proto_codes.def"
};

enum proto_status_bit : uint8_t {
#define PROTO_STATUS(name, bit, text) PROTO_STATUS_##name = 1u << bit,
#include "proto_codes.def"
};

enum proto_error_code : uint8_t {
#define PROTO_ERROR(name, code, text) PROTO_ERR_##name = code,
#include "proto_codes.def"
};

enum proto_cal_reason : uint8_t {
#define PROTO_CAL(name, code, text) PROTO_CAL_##name = code,
#include "proto_codes.def"
};

enum proto_rx_result : uint8_t {
    PROTO_RX_NONE = 0,    // byte consumed, no frame complete (or an empty frame: 0x00 0x00)
    PROTO_RX_FRAME,       // a valid frame is in *out
    PROTO_RX_BAD_CRC,     // dropped
    PROTO_RX_SHORT,       // decoded frame shorter than id + crc: dropped
    PROTO_RX_OVERSIZE,    // more than PROTO_MAX_ENCODED bytes before the delimiter: dropped
    PROTO_RX_BAD_COBS,    // not valid COBS: dropped
    PROTO_RX_UNKNOWN_ID,  // CRC good, id not in the table: out->id/len set, not acted on
    PROTO_RX_BAD_LENGTH,  // CRC good, payload length differs from the table: out->id/len set
    PROTO_RX_CHECK,       // proto_rx_end only: COBS decoded, proto_rx_check does the rest
};

// The whole wire frame of STOP_ALL (no payload): COBS(0x04 | CRC 0xA174, low byte first) and the
// delimiter. Fixed, so that the board's receive interrupt can recognise it byte by byte
// (test_proto.cpp checks it against proto_build).
#define PROTO_STOP_ALL_WIRE \
    { 0x04, 0x04, 0x74, 0xA1, 0x00 }
#define PROTO_STOP_ALL_WIRE_LEN 5

struct proto_frame {
    uint8_t id;
    uint8_t len;             // payload length
    const uint8_t* payload;  // points into the receiver's buffer, valid until the next push
};

struct proto_rx {
    uint8_t buf[PROTO_MAX_ENCODED];
    uint8_t n;  // bytes in buf: encoded while receiving, decoded after proto_rx_end
    uint8_t overflow;
};

// Payload length of a message id from the table, or -1 if the id is unknown.
int16_t proto_payload_len(uint8_t id);

// True for an id of the table that the host sends (H2D). The device answers any other id,
// whatever its length, with UNKNOWN_MESSAGE.
bool proto_to_device(uint8_t id);

void proto_rx_init(proto_rx* rx);

// Append a byte inside a frame (nonzero, room left): true. False for a delimiter or a byte past
// PROTO_MAX_ENCODED, which proto_rx_push must see. Inline: all but one byte of a frame only
// append, and at 1 Mbaud the main loop takes up to 100 bytes a tick.
inline bool proto_rx_append(proto_rx* rx, uint8_t byte) {
    if (byte == 0 || rx->n >= PROTO_MAX_ENCODED) return false;
    rx->buf[rx->n++] = byte;
    return true;
}

// Feed one received byte. Returns PROTO_RX_NONE until a delimiter completes a frame.
proto_rx_result proto_rx_push(proto_rx* rx, uint8_t byte, proto_frame* out);

// proto_rx_push's work at a byte that proto_rx_append refused, in two parts of about half the
// cycles each, so that the board can run a control step between them (a SET_SPEEDS: COBS about
// 430 cycles, CRC and checks about 600): proto_rx_end takes the byte and, at a delimiter,
// decodes the COBS in place and returns PROTO_RX_CHECK for a frame that proto_rx_check must
// finish (CRC, id and length); any other result is final. Feed no byte in between.
proto_rx_result proto_rx_end(proto_rx* rx, uint8_t byte);
proto_rx_result proto_rx_check(proto_rx* rx, proto_frame* out);

// Build the wire bytes (COBS + trailing 0x00) of a message into out (PROTO_MAX_WIRE bytes).
// Returns the number of bytes, or 0 if len > PROTO_MAX_PAYLOAD.
uint8_t proto_build(uint8_t id, const uint8_t* payload, uint8_t len, uint8_t* out);
// proto_build in two parts, for a frame built in slices: raw holds id | payload (body bytes) and
// room for the CRC, which proto_seal appends; proto_wire then writes the COBS and the delimiter
// of the body + 2 raw bytes into out and returns the wire length.
void proto_seal(uint8_t* raw, uint8_t body);
uint8_t proto_wire(const uint8_t* raw, uint8_t raw_len, uint8_t* out);

// Little-endian packing.
void proto_put_u16(uint8_t* p, uint16_t v);
void proto_put_u32(uint8_t* p, uint32_t v);
uint16_t proto_get_u16(const uint8_t* p);
uint32_t proto_get_u32(const uint8_t* p);
inline void proto_put_i32(uint8_t* p, int32_t v) {
    proto_put_u32(p, static_cast<uint32_t>(v));
}
inline int32_t proto_get_i32(const uint8_t* p) {
    return static_cast<int32_t>(proto_get_u32(p));
}

#endif  // PROTO_H
