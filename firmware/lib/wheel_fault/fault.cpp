#include "fault.h"

#include "proto.h"

static_assert(PROTO_FAULT_ENCODER_M3 == (PROTO_FAULT_ENCODER_M0 << 3) &&
                  PROTO_FAULT_ENCODER_M0 == 2u,
              "encoder fault bits of wheels 0..3: bits 1..4 (flt_off_mask, flt_encoder_sample)");

static const uint16_t k_all_off = PROTO_FAULT_STALL | PROTO_FAULT_RUNAWAY;

// Wheels disabled by the latched faults.
static uint8_t flt_off_mask(uint16_t faults) {
    if (faults & k_all_off) return FLT_ALL_WHEELS;
    return static_cast<uint8_t>((faults >> 1) & FLT_ALL_WHEELS);
}

void flt_init(flt_state* f) {
    f->faults = 0;
    f->off_mask = 0;
    f->since_host_ms = 0;
    for (uint8_t w = 0; w < FLT_WHEELS; w++) f->enc_bad[w] = 0;
}

void flt_set(flt_state* f, uint16_t bits) {
    f->faults = static_cast<uint16_t>(f->faults | bits);
    f->off_mask = flt_off_mask(f->faults);
}

void flt_clear(flt_state* f, uint16_t mask) {
    f->faults = static_cast<uint16_t>(f->faults & ~mask);
    f->off_mask = flt_off_mask(f->faults);
    if (mask & PROTO_FAULT_HEARTBEAT_LOST) f->since_host_ms = 0;
    for (uint8_t w = 0; w < FLT_WHEELS; w++) {
        if (mask & (PROTO_FAULT_ENCODER_M0 << w)) f->enc_bad[w] = 0;
    }
}

void flt_host_alive(flt_state* f) {
    f->since_host_ms = 0;
}

bool flt_heartbeat_tick(flt_state* f, uint16_t timeout_ms) {
    if (f->since_host_ms < 0xFFFFu) f->since_host_ms++;
    if (f->since_host_ms >= timeout_ms) flt_set(f, PROTO_FAULT_HEARTBEAT_LOST);
    return (f->faults & PROTO_FAULT_HEARTBEAT_LOST) != 0;
}

bool flt_blocks_setpoints(const flt_state* f) {
    const uint16_t blocking = PROTO_FAULT_HEARTBEAT_LOST | PROTO_FAULT_STALL | PROTO_FAULT_RUNAWAY |
                              PROTO_FAULT_OPEN_LOOP_LIMIT;
    return f->off_mask != 0 || (f->faults & blocking) != 0;
}
