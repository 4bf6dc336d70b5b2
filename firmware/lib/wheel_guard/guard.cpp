#include "guard.h"

#include "enc.h"
#include "proto.h"

static uint16_t grd_count(uint16_t* ticks, bool condition, uint16_t limit) {
    if (!condition) {
        *ticks = 0;
        return 0;
    }
    if (*ticks < 0xFFFFu) (*ticks)++;
    return *ticks >= limit ? 1u : 0u;
}

static int32_t grd_abs(int32_t x) {
    return x < 0 ? -x : x;
}

void grd_reset(grd_wheel* g) {
    *g = grd_wheel();  // all counters and speeds 0
}

uint16_t grd_sensor(grd_wheel* g, const grd_limits* l, uint16_t angle, bool fresh, bool driven) {
    if (!fresh) return 0;  // a bad word: counted by the encoder's bad-word limit instead
    const bool dead = angle == 0 || angle == ENC_MASK;
    const bool same = driven && dead && angle == g->prev_angle;
    g->prev_angle = angle;
    return grd_count(&g->same_ticks, same, l->dead_ticks)
               ? static_cast<uint16_t>(PROTO_FAULT_ENC_STUCK)
               : 0u;
}

// An episode of a motion condition: counted while it holds and the speed has not moved (stall)
// or not come closer to the setpoint (runaway) since the episode began; such progress starts a
// new episode. So a wheel that crosses zero speed while reversing, or that brakes back towards
// its setpoint, never latches however long the drive stays saturated. Inline, and progress only
// computed inside an episode: the common case (no condition) costs a few compares per wheel.
static inline bool grd_episode(uint16_t* ticks, int32_t* from_q8, int32_t speed_q8, bool progress,
                               uint16_t limit) {
    if (*ticks != 0 && progress) *ticks = 0;
    if (*ticks == 0) *from_q8 = speed_q8;
    if (*ticks < 0xFFFFu) (*ticks)++;
    return *ticks >= limit;
}

uint16_t grd_motion(grd_wheel* g, const grd_limits* l, bool looping, bool saturated,
                    int16_t drive_q15, int32_t speed_q8, int32_t sp_q8) {
    if (!looping) {
        g->stall_ticks = 0;
        g->runaway_ticks = 0;
        g->over_ticks = 0;
        return 0;
    }
    uint16_t bits = 0;
    const int32_t speed_abs = grd_abs(speed_q8);
    if (saturated && grd_abs(drive_q15) >= l->drive_min_q15 && speed_abs < l->stall_q8) {
        const bool moved =
            g->stall_ticks != 0 && grd_abs(speed_q8 - g->stall_from_q8) >= l->stall_q8;
        if (grd_episode(&g->stall_ticks, &g->stall_from_q8, speed_q8, moved, l->fault_ticks)) {
            bits |= PROTO_FAULT_STALL;
        }
    } else {
        g->stall_ticks = 0;
    }
    if ((sp_q8 > 0 && speed_q8 < -l->margin_q8) || (sp_q8 < 0 && speed_q8 > l->margin_q8)) {
        const bool closer = g->runaway_ticks != 0 &&
                            grd_abs(sp_q8 - speed_q8) < grd_abs(sp_q8 - g->runaway_from_q8);
        if (grd_episode(&g->runaway_ticks, &g->runaway_from_q8, speed_q8, closer, l->fault_ticks)) {
            bits |= PROTO_FAULT_RUNAWAY;
        }
    } else {
        g->runaway_ticks = 0;
    }
    if (grd_count(&g->over_ticks, speed_abs > l->over_q8, l->fault_ticks)) {
        bits |= PROTO_FAULT_RUNAWAY;
    }
    return bits;
}

uint16_t grd_diag(grd_wheel* g, uint16_t word) {
    uint16_t data = 0;
    const bool good =
        enc_parse(word, &data) == ENC_OK && (data & GRD_DIAG_OCF) && !(data & GRD_DIAG_BAD);
    if (good) {
        g->diag_bad = 0;
        return 0;
    }
    if (g->diag_bad < 0xFFu) g->diag_bad++;
    return g->diag_bad >= GRD_DIAG_LIMIT ? static_cast<uint16_t>(PROTO_FAULT_ENC_DIAG) : 0u;
}
