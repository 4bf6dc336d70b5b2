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

// Record an encoder word of wheel w; returns true if that wheel's encoder fault is latched.
// Inline: it runs for every wheel in every control step.
PORT_INLINE bool flt_encoder_sample(flt_state* f, uint8_t w, bool good, uint8_t limit) {
    uint8_t bad = f->enc_bad[w];
    if (good) {
        bad = 0;
    } else if (bad < 0xFFu) {
        bad++;
    }
    f->enc_bad[w] = bad;
    uint16_t bit = static_cast<uint16_t>(PROTO_FAULT_ENCODER_M0 << w);
    if (bad >= limit) flt_set(f, bit);
    return (f->faults & bit) != 0;
}

// The same with the wheel's counter and fault bit given (the control step walks them).
PORT_INLINE bool flt_encoder_sample_at(flt_state* f, uint8_t* bad_count, uint16_t bit, bool good,
                                       uint8_t limit) {
    uint8_t bad = *bad_count;
    if (good) {
        bad = 0;
    } else if (bad < 0xFFu) {
        bad++;
    }
    *bad_count = bad;
    if (bad >= limit) flt_set(f, bit);
    return (f->faults & bit) != 0;
}

#endif  // FLT_H
