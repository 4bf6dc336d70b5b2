/*
 * sim_uart.h - UART byte time of the real chip in simavr 1.6, for the programs that run the
 * wheel-board ELF (fil_harness.c, bench/cycles.c). Header-only: each program is one file.
 *
 * simavr 1.6 derives its byte time from UBRR without U2X and with 11 bits per byte: at UBRR0 = 1
 * with U2X (1 Mbaud on the ATmega2560, 10 us per 8N1 byte) it sends a byte every 22 us. The
 * firmware's TX interrupts then keep landing in control steps where, on the chip, the telemetry
 * frame is out before the next step starts. sim_uart_chip_timing() sets the module's
 * cycles_per_byte to the chip's value, 10 bits * (U2X ? 8 : 16) * (UBRR + 1) cycles, whenever
 * it differs (simavr recomputes it on every UBRR write); sim_uart_install() has it checked every
 * simulated millisecond.
 */
#ifndef SIM_UART_H
#define SIM_UART_H

#include <simavr/avr_uart.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_io.h>

/* udr_addr: data address of UDRn (0xC6 for UART0 of the ATmega2560). */
static void sim_uart_chip_timing(avr_t* avr, avr_io_addr_t udr_addr) {
    avr_uart_t* u = (avr_uart_t*)avr->io[AVR_DATA_TO_IO(udr_addr)].w.param;
    if (!u || u->r_udr != udr_addr) return;
    uint32_t ubrr = avr_regbit_get(avr, u->ubrrl) | (avr_regbit_get(avr, u->ubrrh) << 8);
    avr_cycle_count_t c = 10u * (avr_regbit_get(avr, u->u2x) ? 8u : 16u) * (ubrr + 1u);
    if (u->cycles_per_byte != c) u->cycles_per_byte = c;
}

static avr_io_addr_t sim_uart_udr;

static avr_cycle_count_t sim_uart_timer(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)param;
    sim_uart_chip_timing(avr, sim_uart_udr);
    return when + avr->frequency / 1000;
}

static void sim_uart_install(avr_t* avr, avr_io_addr_t udr_addr) {
    sim_uart_udr = udr_addr;
    avr_cycle_timer_register(avr, avr->frequency / 1000, sim_uart_timer, NULL);
}

#endif
