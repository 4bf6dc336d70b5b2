#include "params.h"

#include "crc16.h"
#include "port_progmem.h"
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

// The table in flash, one row per id: a switch over params.def compiled into a lookup table
// that avr-gcc keeps in RAM (.data), 63 bytes of the 2048.
struct prm_row {
    int32_t def, lo, hi;
};
static const prm_row prm_rows[PRM_COUNT] PORT_PROGMEM = {
#define PRM(name, id, def, lo, hi, unit, text) {def, lo, hi},
#include "params.def"
#undef PRM
};
// The rows are indexed by id: params.def lists them in id order.
static constexpr uint8_t prm_ids[] = {
#define PRM(name, id, def, lo, hi, unit, text) id,
#include "params.def"
#undef PRM
};
static constexpr bool prm_ids_in_order(uint8_t i) {
    return i == PRM_COUNT || (prm_ids[i] == i && prm_ids_in_order(static_cast<uint8_t>(i + 1)));
}
static_assert(prm_ids_in_order(0), "params.def rows not in id order");

int32_t prm_default(uint8_t id) {
    return id < PRM_COUNT ? PORT_READ_I32(&prm_rows[id].def) : 0;
}

bool prm_in_range(uint8_t id, int32_t value) {
    return id < PRM_COUNT && value >= PORT_READ_I32(&prm_rows[id].lo) &&
           value <= PORT_READ_I32(&prm_rows[id].hi);
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

void prm_image_build(const prm_store* s, uint16_t seq, uint8_t* image) {
    image[0] = 'G';
    image[1] = 'W';
    image[2] = PRM_LAYOUT_VERSION;
    image[3] = PRM_COUNT;
    proto_put_u16(&image[4], seq);
    for (uint8_t i = 0; i < PRM_COUNT; i++) {
        proto_put_i32(&image[PRM_HEADER_SIZE + 4 * i], s->v[i]);
    }
    proto_put_u16(&image[PRM_IMAGE_SIZE - 2], crc16_ccitt(image, PRM_IMAGE_SIZE - 2));
}

bool prm_image_parse(prm_store* s, const uint8_t* image, uint16_t* seq) {
    const uint8_t count = image[3];
    if (image[0] != 'G' || image[1] != 'W' || count < PRM_MIN_COUNT || count > PRM_COUNT) {
        return false;
    }
    uint8_t header;
    if (image[2] == PRM_LAYOUT_VERSION) {
        header = PRM_HEADER_SIZE;
    } else if (image[2] == PRM_LEGACY_VERSION) {
        header = PRM_LEGACY_HEADER_SIZE;
    } else {
        return false;
    }
    const uint8_t body = static_cast<uint8_t>(header + 4 * count);
    if (crc16_ccitt(image, body) != proto_get_u16(&image[body])) return false;
    const uint8_t* values = &image[header];
    for (uint8_t i = 0; i < count; i++) {
        if (!prm_in_range(i, proto_get_i32(&values[4 * i]))) return false;
    }
    if (s) {  // parameters the image predates keep their defaults
        for (uint8_t i = 0; i < count; i++) s->v[i] = proto_get_i32(&values[4 * i]);
    }
    *seq = header == PRM_HEADER_SIZE ? proto_get_u16(&image[4]) : 0;
    return true;
}

static void prm_read_slot(prm_store* s, uint8_t slot) {
    const uint16_t base = PRM_SLOT_ADDR(slot);
    for (uint8_t i = 0; i < PRM_IMAGE_SIZE; i++) {
        s->image[i] = s->ee->read(static_cast<uint16_t>(base + i));
    }
}

bool prm_init(prm_store* s, const prm_eeprom_if* ee) {
    s->ee = ee;
    s->saving = 0;
    s->save_pos = 0;
    s->seq = 0;
    s->slot = 1;  // nothing valid: the first save goes to slot 0
    prm_defaults(s);
    uint16_t seq0 = 0;
    uint16_t seq1 = 0;
    prm_read_slot(s, 0);
    const bool ok0 = prm_image_parse(nullptr, s->image, &seq0);
    prm_read_slot(s, 1);
    const bool ok1 = prm_image_parse(nullptr, s->image, &seq1);
    if (!ok0 && !ok1) return false;
    // Serial-number order: slot 1 is the newer if its sequence number is ahead by 1..32767.
    s->slot =
        (ok1 && (!ok0 || static_cast<int16_t>(static_cast<uint16_t>(seq1 - seq0)) > 0)) ? 1 : 0;
    if (s->slot == 0) prm_read_slot(s, 0);
    return prm_image_parse(s, s->image, &s->seq);
}

void prm_save_begin(prm_store* s) {
    prm_image_build(s, static_cast<uint16_t>(s->seq + 1), s->image);
    s->save_pos = 0;
    s->saving = 1;
}

bool prm_save_poll(prm_store* s) {
    if (!s->saving) return false;
    if (!s->ee->ready()) return false;
    const uint8_t target = static_cast<uint8_t>(s->slot ^ 1);
    const uint16_t base = PRM_SLOT_ADDR(target);
    // Skip bytes that already hold the right value (saves EEPROM wear and time).
    while (s->save_pos < PRM_IMAGE_SIZE &&
           s->ee->read(static_cast<uint16_t>(base + s->save_pos)) == s->image[s->save_pos]) {
        s->save_pos++;
    }
    if (s->save_pos < PRM_IMAGE_SIZE) {
        s->ee->write(static_cast<uint16_t>(base + s->save_pos), s->image[s->save_pos]);
        s->save_pos++;
        return false;
    }
    // The new image is complete: it is the one loaded at the next boot, the next save goes to
    // the other slot.
    s->seq = static_cast<uint16_t>(s->seq + 1);
    s->slot = target;
    s->saving = 0;
    return true;
}
