// flt.h - fault logic: latched fault word, heartbeat supervision, encoder fault counting.
//
// Fault bits are those of proto_codes.def. They latch until flt_clear(); a condition still present
// sets its bit again on the next tick. Heartbeat: any valid frame from the host restarts the
// timer (flt_host_alive); after timeout_ms ticks without one, HEARTBEAT_LOST latches and the
// application forces all setpoints to zero. Blocking faults (heartbeat, encoders) make the device
// refuse new setpoints until cleared.
#ifndef FLT_H
#define FLT_H

#include <stdint.h>

#include "port_progmem.h"
#include "proto.h"

#define FLT_WHEELS 4

struct flt_state {
    uint16_t faults;              // latched PROTO_FAULT_* bits
    uint16_t since_host_ms;       // ticks since the last valid host frame (saturates)
    uint8_t enc_bad[FLT_WHEELS];  // consecutive bad encoder words per wheel (saturates)
};

void flt_init(flt_state* f);
void flt_clear(flt_state* f);

void flt_host_alive(flt_state* f);

// One control tick of heartbeat supervision; returns true while HEARTBEAT_LOST is latched.
bool flt_heartbeat_tick(flt_state* f, uint16_t timeout_ms);

bool flt_wheel_disabled(const flt_state* f, uint8_t w);

// Faults that make the device refuse setpoints.
bool flt_blocks_setpoints(const flt_state* f);

inline void flt_set(flt_state* f, uint16_t bits) {
    f->faults = static_cast<uint16_t>(f->faults | bits);
}

// Record an encoder word of one wheel, given its counter of consecutive bad words and its fault
// bit (PROTO_FAULT_ENCODER_Mw: bits 1..4, in the fault word's low byte); limit >= 1 (params.def).
// Returns true if that wheel's encoder fault is latched. Inline: it runs for every wheel in every
// control step, where a good word costs one store and one bit test.
PORT_INLINE bool flt_encoder_sample(flt_state* f, uint8_t* bad_count, uint8_t bit, bool good,
                                    uint8_t limit) {
    if (good) {
        *bad_count = 0;  // 0 < limit: nothing latches
    } else {
        uint8_t bad = *bad_count;
        if (bad < 0xFFu) bad++;
        *bad_count = bad;
        if (bad >= limit) flt_set(f, bit);
    }
    return (static_cast<uint8_t>(f->faults) & bit) != 0;
}

#endif  // FLT_H
