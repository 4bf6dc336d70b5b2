/*
 * sim_rx.h - UART0's receive side for the FIL harness (fil_harness.c): host bytes at the line
 * rate, host streams generated in simulated time, and a marker for one frame's arrival.
 * Header-only, like sim_uart.h and sim_spi.h: the harness is one file.
 */
#ifndef SIM_RX_H
#define SIM_RX_H

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <simavr/avr_uart.h>
#include <simavr/parts/uart_pty.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_cycle_timers.h>
#include <simavr/sim_io.h>
#include <simavr/sim_irq.h>

#include "sim_uart.h"

/*
 * uart_pty hands the bytes the host wrote to the UART as fast as simavr's receive FIFO (64 bytes)
 * takes them, and simavr 1.6 lets the firmware read two bytes per byte time: a host burst then
 * reaches the firmware at twice the line rate. The harness takes uart_pty's bytes into its own
 * queue (the USB bridge's buffer) and hands the UART one byte per byte time of UBRR0/U2X0. A byte
 * that finds two unread ones (the chip's receive FIFO full) is lost, as a data overrun is.
 */
#define RX_QUEUE_SIZE 4096u /* power of two */
#define RX_QUEUE_HIGH (RX_QUEUE_SIZE - 64u)
static uint8_t g_rxq[RX_QUEUE_SIZE];
static unsigned g_rxq_head, g_rxq_tail; /* both in the simulation thread */
static avr_t* s_avr;
static uart_pty_t* s_pty;
static avr_io_addr_t s_udr;
static unsigned long long
    sim_rx_overrun;           /* received bytes lost: the chip's receive FIFO was full */
static avr_irq_t* g_uart_irq; /* UART0's IRQ block (UART_IRQ_INPUT, _OUT_XON, _XOFF) */
static int g_rx_held;         /* uart_pty told to hold (XOFF) */
/* uart_rx_timer registered. Not avr_cycle_timer_status(): a byte handed to the UART can make
   uart_pty send the next one from inside the timer, which is then off the list, and a second
   timer would double the rate. */
static int g_rx_timer_on;
/* --rx-mark: a frame (bytes before a 0x00) whose delivery is reported as "RXMARK t_us=..." */
static uint8_t g_mark[64];
static unsigned g_mark_len, g_mark_pos; /* g_mark_pos > g_mark_len: this frame differs */

static void rx_mark_track(uint8_t b) {
    if (!g_mark_len) return;
    if (b == 0) {
        if (g_mark_pos == g_mark_len) {
            printf("RXMARK t_us=%llu\n",
                   (unsigned long long)(s_avr->cycle * 1000000ULL / s_avr->frequency));
            fflush(stdout);
        }
        g_mark_pos = 0;
    } else if (g_mark_pos < g_mark_len && g_mark[g_mark_pos] == b) {
        g_mark_pos++;
    } else {
        g_mark_pos = g_mark_len + 1;
    }
}

static avr_uart_t* uart0(void) {
    return (avr_uart_t*)s_avr->io[AVR_DATA_TO_IO(s_udr)].w.param;
}

static avr_cycle_count_t uart_rx_timer(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)param;
    if (g_rxq_head == g_rxq_tail) {
        g_rx_timer_on = 0;
        return 0;
    }
    uint8_t b = g_rxq[g_rxq_tail++ & (RX_QUEUE_SIZE - 1)];
    avr_uart_t* u = uart0();
    unsigned unread = (unsigned)(u->input.write - u->input.read) & (uart_fifo_fifo_size - 1);
    if (unread >= 3) { /* the 2-byte FIFO and the shift register */
        sim_rx_overrun++;
    } else {
        avr_raise_irq(g_uart_irq + UART_IRQ_INPUT, b);
    }
    rx_mark_track(b);
    if (g_rx_held && g_rxq_head - g_rxq_tail < RX_QUEUE_HIGH / 2) {
        g_rx_held = 0;
        avr_raise_irq(g_uart_irq + UART_IRQ_OUT_XON, 1); /* uart_pty may send again */
    }
    sim_uart_chip_timing(avr, s_udr);
    return when + u->cycles_per_byte;
}

/* A byte from uart_pty: queued; above RX_QUEUE_HIGH uart_pty is told to hold (XOFF). */
static void uart_rx_from_pty(struct avr_irq_t* irq, uint32_t value, void* param) {
    (void)irq;
    (void)param;
    if (g_rxq_head - g_rxq_tail >= RX_QUEUE_SIZE) return; /* cannot happen: XOFF below */
    g_rxq[g_rxq_head++ & (RX_QUEUE_SIZE - 1)] = (uint8_t)value;
    if (g_rxq_head - g_rxq_tail >= RX_QUEUE_HIGH) {
        g_rx_held = 1;
        avr_raise_irq(g_uart_irq + UART_IRQ_OUT_XOFF, 1);
    }
    if (!g_rx_timer_on) {
        g_rx_timer_on = 1;
        sim_uart_chip_timing(s_avr, s_udr);
        avr_cycle_timer_register(s_avr, uart0()->cycles_per_byte, uart_rx_timer, NULL);
    }
}

static void sim_rx_install(avr_t* avr, uart_pty_t* pty, avr_io_addr_t udr_addr) {
    s_avr = avr;
    s_pty = pty;
    s_udr = udr_addr;
    g_uart_irq = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_unconnect_irq(s_pty->irq + IRQ_UART_PTY_BYTE_OUT, g_uart_irq + UART_IRQ_INPUT);
    avr_irq_register_notify(s_pty->irq + IRQ_UART_PTY_BYTE_OUT, uart_rx_from_pty, NULL);
}

/* Host bytes generated in simulated time ("rx" and "rx-every" on stdin): a stream whose timing
   no host scheduling can bunch. Each injection is queued as the pty's bytes are. */
typedef struct {
    uint8_t bytes[256];
    unsigned len;
    unsigned period_cycles, count; /* count 0: once */
} rx_inject_t;
#define RX_INJECT_MAX 4
static rx_inject_t g_inject[RX_INJECT_MAX]; /* owned by the simulation thread once active */
static rx_inject_t g_inject_req;            /* from the stdin thread, under g_inject_lock */
static int sim_rx_inject_pending;
static pthread_mutex_t g_inject_lock = PTHREAD_MUTEX_INITIALIZER;

static void rx_queue_bytes(const uint8_t* b, unsigned n) {
    for (unsigned i = 0; i < n; i++) uart_rx_from_pty(NULL, b[i], NULL);
}

static avr_cycle_count_t inject_timer(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)avr;
    rx_inject_t* in = param;
    rx_queue_bytes(in->bytes, in->len);
    if (in->count > 1) {
        in->count--;
        return when + in->period_cycles;
    }
    in->len = 0; /* slot free */
    return 0;
}

/* In the simulation thread: start the injection the stdin thread asked for. */
static void sim_rx_inject_start(void) {
    pthread_mutex_lock(&g_inject_lock);
    rx_inject_t req = g_inject_req;
    sim_rx_inject_pending = 0;
    pthread_mutex_unlock(&g_inject_lock);
    if (req.count == 0) {
        rx_queue_bytes(req.bytes, req.len);
        printf("OK rx %u t_s=%.6f\n", req.len, ((double)s_avr->cycle / (double)s_avr->frequency));
        fflush(stdout);
        return;
    }
    for (int i = 0; i < RX_INJECT_MAX; i++) {
        if (g_inject[i].len) continue;
        g_inject[i] = req;
        avr_cycle_timer_register(s_avr, 1, inject_timer, &g_inject[i]);
        printf("OK rx-every %u t_s=%.6f\n", req.len,
               ((double)s_avr->cycle / (double)s_avr->frequency));
        fflush(stdout);
        return;
    }
    printf("ERR rx-every: %d injections already running\n", RX_INJECT_MAX);
    fflush(stdout);
}

/* "rx HEX" / "rx-every PERIOD_US COUNT HEX" from the stdin thread; 0 if the line is malformed. */
static int sim_rx_inject_request(const char* hex, double period_us, unsigned count) {
    rx_inject_t r = {.len = 0, .count = count};
    size_t n = strlen(hex);
    unsigned v;
    if (n == 0 || n % 2 || n / 2 > sizeof(r.bytes) || period_us < 0) return 0;
    for (size_t i = 0; i < n; i += 2) {
        if (sscanf(hex + i, "%2x", &v) != 1) return 0;
        r.bytes[r.len++] = (uint8_t)v;
    }
    r.period_cycles = (unsigned)(period_us * 1e-6 * (double)s_avr->frequency);
    if (count && r.period_cycles == 0) return 0;
    pthread_mutex_lock(&g_inject_lock);
    g_inject_req = r;
    sim_rx_inject_pending = 1;
    pthread_mutex_unlock(&g_inject_lock);
    return 1;
}

static void sim_rx_parse_mark(const char* s) {
    size_t n = strlen(s);
    unsigned v;
    g_mark_len = 0;
    for (size_t i = 0; i + 1 < n && n % 2 == 0 && g_mark_len < sizeof(g_mark); i += 2) {
        if (sscanf(s + i, "%2x", &v) != 1 || v == 0) break;
        g_mark[g_mark_len++] = (uint8_t)v;
    }
    if (n == 0 || n % 2 || g_mark_len * 2 != n) {
        fprintf(stderr,
                "fil_harness: bad --rx-mark '%s' (want up to 64 nonzero bytes in hex, no 0x00)\n",
                s);
        exit(2);
    }
}

/* After a reset (simavr dropped every cycle timer): restart the pacing if bytes are queued. */
static void sim_rx_reset(avr_t* avr) {
    g_rx_timer_on = g_rxq_head != g_rxq_tail;
    if (g_rx_timer_on) avr_cycle_timer_register(avr, 160, uart_rx_timer, NULL);
}

#endif
