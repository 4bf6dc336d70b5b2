// board_enc_io.h - the encoder reads of the control step (app_step.h's Io) on the SPI master:
// encoder 0 is read at once, encoder i+1 in five stages between the arithmetic of wheel i, so the
// 8 SCK periods of each byte (16 cycles at clk/2) run while the CPU computes instead of polling.
// Frames as enc.h and board_spi.cpp: per encoder a command frame and a reply frame (0xFFFF each),
// CS high >= 375 ns between them, CS low >= 375 ns before the clock.
#ifndef BOARD_ENC_IO_H
#define BOARD_ENC_IO_H

#include "board.h"
#include "board_io.h"
#include "enc.h"

#define BOARD_INLINE inline __attribute__((always_inline))

// The diagnostics register (0x3FFD) of one encoder, 0..3: a read command frame, then a read-angle
// frame whose reply is the register (about 10 us; after the step, in the tick's spare time). The
// next step's command frame is answered with the angle as usual.
uint16_t enc_read_diag(uint8_t wheel);

// Six NOPs: 375 ns at 16 MHz (AS5048A: >= 350 ns).
static BOARD_INLINE void board_wait_350ns() {
    __asm__ __volatile__("nop\n\tnop\n\tnop\n\tnop\n\tnop\n\tnop" ::);
}

// The byte of the transfer in progress; SPIF is set 8 SCK periods after the SPDR write (usually
// already by the time a stage runs).
static BOARD_INLINE uint8_t board_spi_collect() {
    while (!(SPSR & _BV(SPIF))) {
    }
    return SPDR;
}

struct board_enc_io {
    uint8_t cs;  // chip-select bit of the encoder being read, 0 after the last one
    uint8_t hi;
    uint16_t next_word;

    uint16_t first() {
        uint16_t w0[BOARD_WHEELS];
        enc_read_one(w0, static_cast<uint8_t>(1u << BOARD_CS_SHIFT));
        cs = static_cast<uint8_t>(2u << BOARD_CS_SHIFT);
        return w0[0];
    }
    BOARD_INLINE void next(uint8_t k) {
        if (!cs) return;
        switch (k) {
            case 0:  // command frame, first byte
                BOARD_CS_PORT &= static_cast<uint8_t>(~cs);
                board_wait_350ns();
                SPDR = static_cast<uint8_t>(ENC_CMD_READ_ANGLE >> 8);
                break;
            case 1:  // command frame, second byte
                (void)board_spi_collect();
                SPDR = static_cast<uint8_t>(ENC_CMD_READ_ANGLE & 0xFF);
                break;
            case 2:  // end of the command frame (the sensor latches the angle), reply frame
                (void)board_spi_collect();
                BOARD_CS_PORT |= cs;
                board_wait_350ns();
                BOARD_CS_PORT &= static_cast<uint8_t>(~cs);
                board_wait_350ns();
                SPDR = static_cast<uint8_t>(ENC_CMD_READ_ANGLE >> 8);
                break;
            case 3:
                hi = board_spi_collect();
                SPDR = static_cast<uint8_t>(ENC_CMD_READ_ANGLE & 0xFF);
                break;
            default:  // 4: reply complete
                next_word =
                    static_cast<uint16_t>((static_cast<uint16_t>(hi) << 8) | board_spi_collect());
                BOARD_CS_PORT |= cs;
                cs = static_cast<uint8_t>(cs << 1);
                break;
        }
    }
    uint16_t word(uint8_t) { return next_word; }
};

#endif  // BOARD_ENC_IO_H
