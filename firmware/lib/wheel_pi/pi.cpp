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
    const pi_gains gs = pi_gains_sanitize(*g);
    return pi_step_err(s, &gs, setpoint - measured);
}
