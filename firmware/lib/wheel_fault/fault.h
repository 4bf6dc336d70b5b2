// fault.h - fault logic: latched fault word, heartbeat supervision, encoder fault counting, the
// wheels a latched fault disables.
//
// Fault bits are those of proto_codes.def. They latch until flt_clear() names them; a condition
// still present sets its bit again on the next tick. Heartbeat: a valid control frame from the
// host (HEARTBEAT, SET_SPEEDS, STOP_ALL) restarts the timer (flt_host_alive); queries do not.
// After timeout_ms ticks without one, HEARTBEAT_LOST
// latches and the application forces all setpoints to zero. An ENCODER_Mw bit disables wheel w;
// STALL or RUNAWAY disables every wheel (the loop itself is suspect). Blocking faults (heartbeat,
// encoders, stall, runaway, the open-loop time limit) make the device refuse new setpoints until
// cleared.
#ifndef FAULT_H
#define FAULT_H

#include <stdint.h>

#include "port_progmem.h"
#include "proto.h"

#define FLT_WHEELS 4
#define FLT_ALL_WHEELS 0x0Fu

struct flt_state {
    uint16_t faults;              // latched PROTO_FAULT_* bits
    uint16_t since_host_ms;       // ticks since the last host control frame (saturates)
    uint8_t off_mask;             // bit w: wheel w disabled by a latched fault (flt_off_mask)
    uint8_t enc_bad[FLT_WHEELS];  // consecutive bad encoder words per wheel (saturates)
};

void flt_init(flt_state* f);

// Clear the latched bits in mask (and the counters behind them); the others stay.
void flt_clear(flt_state* f, uint16_t mask);

void flt_host_alive(flt_state* f);

// One control tick of heartbeat supervision; returns true while HEARTBEAT_LOST is latched.
bool flt_heartbeat_tick(flt_state* f, uint16_t timeout_ms);

// Latch fault bits.
void flt_set(flt_state* f, uint16_t bits);

PORT_INLINE bool flt_wheel_disabled(const flt_state* f, uint8_t w) {
    return (f->off_mask >> w) & 1u;
}

// Faults that make the device refuse setpoints.
bool flt_blocks_setpoints(const flt_state* f);

// Record an encoder word of one wheel, given its counter of consecutive bad words and its wheel
// bit (1 << w; its fault bit PROTO_FAULT_ENCODER_Mw is the next one up); limit >= 1
// (params.def). Returns true if the wheel is disabled by a latched fault. Inline: it runs for
// every wheel in every control step, where a good word costs one store and one bit test.
PORT_INLINE bool flt_encoder_sample(flt_state* f, uint8_t* bad_count, uint8_t wheel_bit, bool good,
                                    uint8_t limit) {
    if (good) {
        *bad_count = 0;  // 0 < limit: nothing latches
    } else {
        uint8_t bad = *bad_count;
        if (bad < 0xFFu) bad++;
        *bad_count = bad;
        if (bad >= limit) flt_set(f, static_cast<uint16_t>(PROTO_FAULT_ENCODER_M0 * wheel_bit));
    }
    return (f->off_mask & wheel_bit) != 0;
}

#endif  // FAULT_H
