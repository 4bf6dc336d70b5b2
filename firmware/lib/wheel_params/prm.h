// prm.h - parameter store: RAM values, range checks, EEPROM image with version and checksum.
//
// EEPROM image at address 0 (PRM_IMAGE_SIZE bytes):
//   0..1 magic 'G' 'W' | 2 layout version | 3 parameter count | 4.. int32 values LE, id order |
//   CRC-16/CCITT-FALSE of all preceding bytes, LE.
// An image with a wrong magic, version, count, CRC or any value out of range is ignored and the
// defaults are used. Saving never blocks: prm_save_poll() writes at most one byte per call and
// only when the EEPROM is ready (one byte takes 3.3 ms on the ATmega2560), skipping equal bytes.
#ifndef PRM_H
#define PRM_H

#include <stdint.h>

enum prm_id : uint8_t {
#define PRM(name, id, def, lo, hi, unit, text) PRM_##name = id,
#include "params.def"
#undef PRM
};

#define PRM_COUNT 19
#define PRM_LAYOUT_VERSION 2
#define PRM_IMAGE_SIZE (4 + 4 * PRM_COUNT + 2)

// The EEPROM behind a tiny interface: the board implements it on avr-libc, tests on a RAM array.
struct prm_eeprom_if {
    uint8_t (*read)(uint16_t addr);
    bool (*ready)();
    void (*write)(uint16_t addr, uint8_t value);  // only called when ready() is true
};

enum prm_result : uint8_t {
    PRM_OK = 0,
    PRM_UNKNOWN = 1,
    PRM_OUT_OF_RANGE = 2,
};

struct prm_store {
    int32_t v[PRM_COUNT];
    const prm_eeprom_if* ee;
    uint8_t image[PRM_IMAGE_SIZE];  // snapshot being written by a save
    uint8_t save_pos;
    uint8_t saving;
};

int32_t prm_default(uint8_t id);
bool prm_in_range(uint8_t id, int32_t value);
void prm_defaults(prm_store* s);

// Set a value after checking id and range; the store is unchanged on error.
prm_result prm_set(prm_store* s, uint8_t id, int32_t value);

// Serialize the current values into image (PRM_IMAGE_SIZE bytes).
void prm_image_build(const prm_store* s, uint8_t* image);

// Check an image; on success copy its values into s. Returns true if it was valid.
bool prm_image_parse(prm_store* s, const uint8_t* image);

// Attach the EEPROM and load from it; false (and defaults) if the image is invalid.
bool prm_init(prm_store* s, const prm_eeprom_if* ee);

// Start saving a snapshot of the current values.
void prm_save_begin(prm_store* s);

// Advance a save by at most one byte; returns true exactly once, when the save completes.
bool prm_save_poll(prm_store* s);

#endif  // PRM_H
