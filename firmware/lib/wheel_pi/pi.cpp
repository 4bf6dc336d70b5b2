#include "pi.h"

void pi_reset(pi_state* s) {
    s->integ = 0;
    s->out = 0;
    s->saturated = 0;
}

pi_gains pi_gains_sanitize(pi_gains g) {
    if (g.out_max < 0) g.out_max = 0;
    if (g.slew < 1) g.slew = 1;
    return g;
}

int16_t pi_step(pi_state* s, const pi_gains* g, int32_t setpoint, int32_t measured) {
    int32_t e = setpoint - measured;
    const bool neg = e < 0;
    uint16_t mag;
    if (e > PI_ERR_CLAMP || e < -PI_ERR_CLAMP) {
        mag = static_cast<uint16_t>(PI_ERR_CLAMP);
    } else {
        mag = static_cast<uint16_t>(neg ? -e : e);
    }
    const pi_gains gs = pi_gains_sanitize(*g);
    return pi_step_mag(s, &gs, neg, mag);
}
