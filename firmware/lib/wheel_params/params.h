// params.h - parameter store: RAM values, range checks, EEPROM images with sequence number and CRC.
//
// Two EEPROM slots of one image each, at PRM_SLOT_ADDR(0) = 0 and PRM_SLOT_ADDR(1) = 128:
//   0..1 magic 'G' 'W' | 2 layout version | 3 parameter count | 4..5 sequence number LE |
//   6.. int32 values LE, id order | CRC-16/CCITT-FALSE of all preceding bytes, LE.
// A slot with a wrong magic, version, count (PRM_MIN_COUNT..PRM_COUNT), CRC or any value out of
// range is ignored. At boot the
// valid slot with the newer sequence number (serial-number order, 16 bits) is loaded; with none
// valid the defaults are used. A save writes the other slot with the next sequence number, so a
// power cut at any byte of it leaves the slot loaded before intact: the next boot loads either
// that set or, once the new image is complete with its CRC, the new one. A layout-2 image at
// slot 0 (no sequence number, 82 bytes) is still loaded, as sequence 0.
// Saving never blocks: prm_save_poll() writes at most one byte per call and only when the EEPROM
// is ready (one byte takes 3.3 ms on the ATmega2560), skipping equal bytes.
#ifndef PARAMS_H
#define PARAMS_H

#include <stdint.h>

enum prm_id : uint8_t {
#define PRM(name, id, def, lo, hi, unit, text) PRM_##name = id,
#include "params.def"
#undef PRM
};

#define PRM_COUNT 22
// Images of earlier firmware hold the first 19 parameters (up to ENC_OFFSET_M3): still loaded, the
// parameters after them at their defaults, so an update keeps the calibrated offsets.
#define PRM_MIN_COUNT 19
#define PRM_LAYOUT_VERSION 3
#define PRM_HEADER_SIZE 6
#define PRM_IMAGE_SIZE (PRM_HEADER_SIZE + 4 * PRM_COUNT + 2)
#define PRM_LEGACY_VERSION 2  // header of 4 bytes: no sequence number
#define PRM_LEGACY_HEADER_SIZE 4
#define PRM_SLOT_STRIDE 128
#define PRM_SLOT_ADDR(slot) (static_cast<uint16_t>((slot)*PRM_SLOT_STRIDE))
#define PRM_EEPROM_USED (PRM_SLOT_STRIDE + PRM_IMAGE_SIZE)  // bytes from address 0 the store uses
static_assert(PRM_IMAGE_SIZE <= PRM_SLOT_STRIDE, "an image must fit its slot");

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
    uint16_t seq;                   // sequence number of the newest valid slot (0: none)
    uint8_t slot;                   // that slot; a save writes the other one
    uint8_t save_pos;
    uint8_t saving;
};

int32_t prm_default(uint8_t id);
bool prm_in_range(uint8_t id, int32_t value);
void prm_defaults(prm_store* s);

// Set a value after checking id and range; the store is unchanged on error.
prm_result prm_set(prm_store* s, uint8_t id, int32_t value);

// Serialize the current values with sequence number seq into image (PRM_IMAGE_SIZE bytes).
void prm_image_build(const prm_store* s, uint16_t seq, uint8_t* image);

// Check an image (layout 3, or layout 2 as sequence 0); on success copy its values into s (unless
// s is null: check only) and its sequence number into *seq. Returns true if it was valid; s is
// unchanged otherwise.
bool prm_image_parse(prm_store* s, const uint8_t* image, uint16_t* seq);

// Attach the EEPROM and load the newest valid slot; false (and defaults) if neither is valid.
bool prm_init(prm_store* s, const prm_eeprom_if* ee);

// Start saving a snapshot of the current values into the slot not loaded last.
void prm_save_begin(prm_store* s);

// Advance a save by at most one byte; returns true exactly once, when the save completes.
bool prm_save_poll(prm_store* s);

#endif  // PARAMS_H
