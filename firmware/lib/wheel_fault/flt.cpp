#include "flt.h"

#include "proto.h"

static_assert(PROTO_FAULT_ENCODER_M3 == (PROTO_FAULT_ENCODER_M0 << 3) &&
                  PROTO_FAULT_ENCODER_M3 <= 0xFF,
              "encoder fault bits of wheels 0..3: adjacent, in the low byte (flt_encoder_sample)");

static uint16_t flt_encoder_bit(uint8_t w) {
    return static_cast<uint16_t>(PROTO_FAULT_ENCODER_M0 << w);
}

void flt_init(flt_state* f) {
    f->faults = 0;
    f->since_host_ms = 0;
    for (uint8_t w = 0; w < FLT_WHEELS; w++) f->enc_bad[w] = 0;
}

void flt_clear(flt_state* f) {
    f->faults = 0;
    f->since_host_ms = 0;
    for (uint8_t w = 0; w < FLT_WHEELS; w++) f->enc_bad[w] = 0;
}

void flt_host_alive(flt_state* f) {
    f->since_host_ms = 0;
}

bool flt_heartbeat_tick(flt_state* f, uint16_t timeout_ms) {
    if (f->since_host_ms < 0xFFFFu) f->since_host_ms++;
    if (f->since_host_ms >= timeout_ms) flt_set(f, PROTO_FAULT_HEARTBEAT_LOST);
    return (f->faults & PROTO_FAULT_HEARTBEAT_LOST) != 0;
}

bool flt_wheel_disabled(const flt_state* f, uint8_t w) {
    return (f->faults & flt_encoder_bit(w)) != 0;
}

bool flt_blocks_setpoints(const flt_state* f) {
    const uint16_t blocking = PROTO_FAULT_HEARTBEAT_LOST | PROTO_FAULT_ENCODER_M0 |
                              PROTO_FAULT_ENCODER_M1 | PROTO_FAULT_ENCODER_M2 |
                              PROTO_FAULT_ENCODER_M3;
    return (f->faults & blocking) != 0;
}
