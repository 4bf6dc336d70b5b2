/*
 * sim_spi.h - SPI master transfers at the real SCK rate in simavr 1.6, for the programs that run
 * the wheel-board ELF (fil_harness.c, bench/cycles.c). Header-only: each program is one file.
 *
 * simavr 1.6 completes every SPDR write after a fixed 100 us (avr_spi.c:
 * avr_cycle_timer_register_usec(avr, 100, ...)), which would charge the firmware 1,600 cycles per
 * byte instead of 8 SCK periods. sim_spi_install() takes over the SPDR write: the byte completes
 * after 8 * (SPI clock divider) CPU cycles, the slave's answer (from the program's exchange
 * function, given the byte the master sent) goes into simavr's input register and SPIF is raised
 * through simavr's own interrupt vector (so SPIE works too); the SPDR read stays simavr's.
 */
#ifndef SIM_SPI_H
#define SIM_SPI_H

#include <stdint.h>
#include <stdio.h>

#include <simavr/avr_spi.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_io.h>

/* The slave side: the byte on MISO for the byte the master shifted out on MOSI. */
typedef uint8_t (*sim_spi_exchange_fn)(uint8_t mosi);

static avr_spi_t* sim_spi;
static uint8_t sim_spi_mosi;
static sim_spi_exchange_fn sim_spi_exchange;

static avr_cycle_count_t sim_spi_byte_done(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)when;
    (void)param;
    sim_spi->input_data_register = sim_spi_exchange(sim_spi_mosi);
    avr_raise_interrupt(avr, &sim_spi->spi);
    return 0;
}

/* CPU cycles of one byte: 8 SCK periods at the divider set by SPR1:0 and SPI2X. */
static uint32_t sim_spi_byte_cycles(avr_t* avr) {
    static const uint32_t div[4] = {4, 16, 64, 128};
    uint32_t d =
        div[avr_regbit_get(avr, sim_spi->spr[0]) | (avr_regbit_get(avr, sim_spi->spr[1]) << 1)];
    if (avr_regbit_get(avr, sim_spi->spr[2])) d /= 2;
    return 8 * d;
}

static void sim_spi_spdr_write(avr_t* avr, avr_io_addr_t addr, uint8_t v, void* param) {
    (void)param;
    avr->data[addr] = v;
    if (!avr_regbit_get(avr, sim_spi->spe) || !avr_regbit_get(avr, sim_spi->mstr)) return;
    avr_regbit_clear(avr, sim_spi->spi.raised);
    sim_spi_mosi = v;
    avr_cycle_timer_cancel(avr, sim_spi_byte_done, NULL);
    avr_cycle_timer_register(avr, sim_spi_byte_cycles(avr), sim_spi_byte_done, NULL);
}

/* Replace simavr's SPDR write at data address spdr_addr; 0 on success, -1 (reported) if the SPI
 * module is not there. */
static int sim_spi_install(avr_t* avr, avr_io_addr_t spdr_addr, sim_spi_exchange_fn exchange) {
    sim_spi = (avr_spi_t*)avr->io[AVR_DATA_TO_IO(spdr_addr)].w.param;
    if (!sim_spi || sim_spi->r_spdr != spdr_addr) {
        fprintf(stderr, "SPI module not found at SPDR 0x%02x\n", (unsigned)spdr_addr);
        return -1;
    }
    sim_spi_exchange = exchange;
    avr->io[AVR_DATA_TO_IO(spdr_addr)].w.c = sim_spi_spdr_write;
    avr->io[AVR_DATA_TO_IO(spdr_addr)].w.param = NULL;
    return 0;
}

#endif
