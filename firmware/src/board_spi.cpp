// board_spi.cpp - AS5048A encoders on the hardware SPI master, polled (about 40 us for all four;
// the control step reads encoders 1..3 overlapped with its arithmetic, board_enc_io.h).
#include "board.h"
#include "board_io.h"
#include "enc.h"
#include "guard.h"

// AS5048A timing: CSn high >= 350 ns between frames, CSn low to first clock >= 350 ns.
// Six NOPs are 375 ns at 16 MHz.
static inline __attribute__((always_inline)) void spi_wait_350ns() {
    __asm__ __volatile__("nop\n\tnop\n\tnop\n\tnop\n\tnop\n\tnop" ::);
}

void spi_init() {
    BOARD_CS_PORT |= BOARD_CS_MASK;  // all chip selects high (inactive)
    BOARD_CS_DDR |= BOARD_CS_MASK;
    BOARD_SPI_DDR |= BOARD_SPI_OUT_PINS;
    BOARD_SPI_PORT |= BOARD_SPI_MISO_PULLUP;
    SPCR = BOARD_SPI_SPCR;
    SPSR = BOARD_SPI_SPSR;
}

static inline __attribute__((always_inline)) uint8_t spi_xfer(uint8_t out) {
    SPDR = out;
    while (!(SPSR & _BV(SPIF))) {
    }
    return SPDR;
}

// One 16-bit frame; the 8 SCK periods of each byte (16 cycles at clk/2) are the bulk of it.
static inline __attribute__((always_inline)) uint16_t enc_frame(uint8_t cs_bit, uint16_t cmd) {
    BOARD_CS_PORT &= static_cast<uint8_t>(~cs_bit);
    spi_wait_350ns();
    uint8_t hi = spi_xfer(static_cast<uint8_t>(cmd >> 8));
    uint8_t lo = spi_xfer(static_cast<uint8_t>(cmd & 0xFF));
    BOARD_CS_PORT |= cs_bit;
    spi_wait_350ns();
    return static_cast<uint16_t>((static_cast<uint16_t>(hi) << 8) | lo);
}

void enc_read_one(uint16_t words[1], uint8_t cs_bit) {
    (void)enc_frame(cs_bit, ENC_CMD_READ_ANGLE);
    words[0] = enc_frame(cs_bit, ENC_CMD_READ_ANGLE);
}

void enc_clear_errors(uint8_t mask) {
    for (uint8_t cs = static_cast<uint8_t>(1u << BOARD_CS_SHIFT); mask; cs <<= 1, mask >>= 1) {
        if (mask & 1u) (void)enc_frame(cs, ENC_CMD_CLEAR_ERROR);
    }
}

uint16_t enc_read_diag(uint8_t wheel) {
    const uint8_t cs = static_cast<uint8_t>(1u << (BOARD_CS_SHIFT + wheel));
    (void)enc_frame(cs, GRD_CMD_READ_DIAG);
    return enc_frame(cs, ENC_CMD_READ_ANGLE);  // the reply to the read: the register
}
