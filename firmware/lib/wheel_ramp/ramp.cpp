#include "ramp.h"

int32_t ramp_step(int32_t value, int32_t target, int32_t step) {
    if (step < 1) step = 1;
    // The gap is taken as unsigned so that even int32 extremes cannot overflow.
    uint32_t ustep = static_cast<uint32_t>(step);
    if (target > value) {
        uint32_t gap = static_cast<uint32_t>(target) - static_cast<uint32_t>(value);
        return (gap > ustep) ? value + step : target;
    }
    if (target < value) {
        uint32_t gap = static_cast<uint32_t>(value) - static_cast<uint32_t>(target);
        return (gap > ustep) ? value - step : target;
    }
    return value;
}
