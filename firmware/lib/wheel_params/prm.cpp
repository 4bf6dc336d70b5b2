#include "prm.h"

#include "crc16.h"
#include "proto.h"

#define PRM(name, id, def, lo, hi, unit, text)                    \
    static_assert((lo) <= (def) && (def) <= (hi), "bad default"); \
    static_assert((id) < PRM_COUNT, "id beyond PRM_COUNT");
#include "params.def"
#undef PRM

enum : uint8_t {
    prm_entries = 0
#define PRM(name, id, def, lo, hi, unit, text) +1
#include "params.def"
#undef PRM
};
static_assert(prm_entries == PRM_COUNT, "PRM_COUNT differs from the number of rows in params.def");

int32_t prm_default(uint8_t id) {
    switch (id) {
#define PRM(name, id, def, lo, hi, unit, text) \
    case id:                                   \
        return def;
#include "params.def"
#undef PRM
        default:
            return 0;
    }
}

bool prm_in_range(uint8_t id, int32_t value) {
    switch (id) {
#define PRM(name, id, def, lo, hi, unit, text) \
    case id:                                   \
        return value >= (lo) && value <= (hi);
#include "params.def"
#undef PRM
        default:
            return false;
    }
}

void prm_defaults(prm_store* s) {
    for (uint8_t i = 0; i < PRM_COUNT; i++) s->v[i] = prm_default(i);
}

prm_result prm_set(prm_store* s, uint8_t id, int32_t value) {
    if (id >= PRM_COUNT) return PRM_UNKNOWN;
    if (!prm_in_range(id, value)) return PRM_OUT_OF_RANGE;
    s->v[id] = value;
    return PRM_OK;
}

void prm_image_build(const prm_store* s, uint8_t* image) {
    image[0] = 'G';
    image[1] = 'W';
    image[2] = PRM_LAYOUT_VERSION;
    image[3] = PRM_COUNT;
    for (uint8_t i = 0; i < PRM_COUNT; i++) proto_put_i32(&image[4 + 4 * i], s->v[i]);
    proto_put_u16(&image[PRM_IMAGE_SIZE - 2], crc16_ccitt(image, PRM_IMAGE_SIZE - 2));
}

bool prm_image_parse(prm_store* s, const uint8_t* image) {
    if (image[0] != 'G' || image[1] != 'W') return false;
    if (image[2] != PRM_LAYOUT_VERSION || image[3] != PRM_COUNT) return false;
    if (crc16_ccitt(image, PRM_IMAGE_SIZE - 2) != proto_get_u16(&image[PRM_IMAGE_SIZE - 2])) {
        return false;
    }
    for (uint8_t i = 0; i < PRM_COUNT; i++) {
        if (!prm_in_range(i, proto_get_i32(&image[4 + 4 * i]))) return false;
    }
    for (uint8_t i = 0; i < PRM_COUNT; i++) s->v[i] = proto_get_i32(&image[4 + 4 * i]);
    return true;
}

bool prm_init(prm_store* s, const prm_eeprom_if* ee) {
    s->ee = ee;
    s->saving = 0;
    s->save_pos = 0;
    prm_defaults(s);
    for (uint8_t i = 0; i < PRM_IMAGE_SIZE; i++) s->image[i] = ee->read(i);
    return prm_image_parse(s, s->image);
}

void prm_save_begin(prm_store* s) {
    prm_image_build(s, s->image);
    s->save_pos = 0;
    s->saving = 1;
}

bool prm_save_poll(prm_store* s) {
    if (!s->saving) return false;
    if (!s->ee->ready()) return false;
    // Skip bytes that already hold the right value (saves EEPROM wear and time).
    while (s->save_pos < PRM_IMAGE_SIZE && s->ee->read(s->save_pos) == s->image[s->save_pos]) {
        s->save_pos++;
    }
    if (s->save_pos < PRM_IMAGE_SIZE) {
        s->ee->write(s->save_pos, s->image[s->save_pos]);
        s->save_pos++;
        return false;
    }
    s->saving = 0;
    return true;
}
