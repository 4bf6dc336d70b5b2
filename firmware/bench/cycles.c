/*
 * cycles.c - control-step and ISR cycle counts of the wheel-board firmware in simavr.
 *
 * Usage: cycles firmware.elf <TIMER2_COMPA addr> <USART0_RX addr> <USART0_UDRE addr>
 * (byte addresses of the ISR functions, from avr-nm; `make -C firmware cycles` passes them).
 *
 * Drives the firmware like a host would: HELLO, HEARTBEAT_MS 1000 (its limit) and a HEARTBEAT
 * every 100 ms, closed-loop setpoints at 715 rpm (+ - + - for wheels 0..3), then runs 2 s of
 * simulated time. Encoders answer on SPI
 * with an angle rotating at 195 counts per 1 ms (about 715 rpm) in the direction of their wheel's
 * setpoint (the selected encoder is the one whose chip select, PA4..PA7, is low). Reports the
 * control step (cycles between the writes GPIOR0 = 1 and GPIOR0 = 0: encoder reads, estimator, PI,
 * commutation of all four wheels), the same without the ISRs that preempted it, the main-loop rate
 * (control steps per simulated second), each ISR from its first instruction to its reti inclusive
 * (the interrupt response and vector jump add 8 cycles on the ATmega2560, not included), the bytes
 * and frames sent on UART0, the main loop's work per tick (GPIOR1 = 1 .. 0: step, PWM, the jobs
 * after it to the last telemetry slice), a telemetry slice (GPIOR2 = 1 .. 0 around the call),
 * the ISR load per tick and the CPU load per tick (that work plus the ISRs outside it), and the
 * deepest stack (lowest SP after every instruction).
 *
 * UART timing: simavr 1.6 sends a byte every 22 us at UBRR0 = 1 with U2X (it ignores U2X and
 * counts 11 bits), where the ATmega2560 takes 10 us (1 Mbaud): the bench sets the chip's byte
 * time (sim/sim_uart.h), so the TX interrupts land in the steps as often as on the board.
 *
 * SPI timing: simavr 1.6 completes every SPDR write after a fixed 100 us (1,600 cycles) whatever
 * the SPI clock. The bench takes over the SPDR write like firmware/sim/fil_harness.c does: the
 * byte completes after 8 SCK periods (8 * SPI clock divider CPU cycles), the reply goes into
 * simavr's input register and SPIF is raised through simavr's interrupt vector (sim/sim_spi.h).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <simavr/avr_spi.h>
#include <simavr/avr_uart.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_io.h>
#include <simavr/sim_irq.h>

#include "../sim/sim_spi.h"
#include "../sim/sim_uart.h"

#define ADDR_GPIOR0 0x3E
#define ADDR_GPIOR1 0x4A
#define ADDR_GPIOR2 0x4B
#define ADDR_SPL 0x5D
#define ADDR_SPH 0x5E
#define RAMEND 0x21FF

typedef struct {
    const char* name;
    uint32_t addr;
    uint64_t start, n, sum, min, max;
    int in, in_step, outside;
} isr_stat_t;

#define ADDR_SPDR 0x4E
#define ADDR_UDR0 0xC6
#define ADDR_PORTA 0x22
#define TICK_CYCLES 16000u

static uint64_t g_mark_start, g_steps, g_sum, g_min = UINT64_MAX, g_max;
static uint64_t g_first_mark, g_last_mark;
/* ISR cycles (+8 entry each) while measuring: in total, inside the step, outside the tick work */
static uint64_t g_isr_all, g_isr_in_step, g_isr_outside;
/* The step without the ISRs that preempted it */
static uint64_t g_isr_this_step, g_pure_sum, g_pure_max, g_pure_min = UINT64_MAX;
static avr_t* g_avr;
static uint16_t g_angle, g_word;
static int g_byte_index;
static uint64_t* g_profile; /* cycles per flash word inside the control step (PROFILE=file) */

static void gpior0_write(avr_t* avr, avr_io_addr_t addr, uint8_t v, void* param) {
    (void)param;
    avr->data[addr] = v;
    if (v == 1) {
        g_mark_start = avr->cycle;
        g_isr_this_step = 0;
    } else if (g_mark_start) {
        uint64_t d = avr->cycle - g_mark_start;
        g_mark_start = 0;
        if (g_steps++ < 5) return; /* skip start-up steps */
        uint64_t pure = d - g_isr_this_step;
        g_pure_sum += pure;
        if (pure < g_pure_min) g_pure_min = pure;
        if (pure > g_pure_max) g_pure_max = pure;
        if (!g_first_mark) g_first_mark = avr->cycle;
        g_last_mark = avr->cycle;
        g_sum += d;
        if (d < g_min) g_min = d;
        if (d > g_max) g_max = d;
    }
}

/* A window the firmware marks by writing 1 to a GPIOR at its start and 0 at its end. */
typedef struct {
    uint64_t min_cycles; /* shorter windows are not counted */
    uint64_t start, n, sum, max, min;
} window_t;

/* GPIOR1: the main loop's work on a tick (step, PWM, the jobs after it, telemetry slices). */
static window_t g_tick = {0, 0, 0, 0, 0, UINT64_MAX};

/* GPIOR2: one call for a telemetry slice (app_telemetry_work). A window longer than 100 cycles
 * did a slice (speed conversions, CRC, COBS or the TX ring copy); the others found none to do
 * (about 20 cycles, more when an interrupt lands in them). */
static window_t g_telem = {100u, 0, 0, 0, 0, UINT64_MAX};

static void window_write(avr_t* avr, avr_io_addr_t addr, uint8_t v, void* param) {
    window_t* w = (window_t*)param;
    avr->data[addr] = v;
    if (v == 1) {
        w->start = avr->cycle;
        return;
    }
    if (!w->start) return;
    uint64_t d = avr->cycle - w->start;
    w->start = 0;
    if (!g_first_mark || d < w->min_cycles) return; /* start-up, or too short */
    w->n++;
    w->sum += d;
    if (d < w->min) w->min = d;
    if (d > w->max) w->max = d;
}

/* Lowest stack pointer of the whole run (the stack grows down from RAMEND). */
static uint16_t g_sp_min = 0xFFFF;

/* Bytes and frames (zero delimiters) the firmware sent on UART0. */
static uint64_t g_tx_bytes, g_tx_frames;
static void uart_out(struct avr_irq_t* irq, uint32_t value, void* param) {
    (void)irq;
    (void)param;
    g_tx_bytes++;
    if ((value & 0xFF) == 0) g_tx_frames++;
}

static uint16_t enc_word(uint16_t angle) {
    uint16_t w = angle & 0x3FFF;
    int ones = __builtin_popcount(w);
    return (ones & 1) ? (uint16_t)(w | 0x8000) : w;
}

/* The encoder's reply byte to the byte the firmware just sent: the angle, or after a read of the
 * diagnostics register (0x7FFD) that register (OCF set: a healthy sensor). */
static uint8_t encoder_byte(uint8_t mosi) {
    static uint16_t last_cmd[4], cmd;
    static int enc;
    if (g_byte_index == 0) {
        uint8_t cs = g_avr->data[ADDR_PORTA] >> 4; /* active low, bit i = encoder i */
        enc = !(cs & 0x1) ? 0 : !(cs & 0x2) ? 1 : !(cs & 0x4) ? 2 : 3;
        g_angle = (uint16_t)((g_avr->cycle / TICK_CYCLES) * 195u); /* 195 counts per ms */
        if (enc & 1) g_angle = (uint16_t)(0u - g_angle); /* wheels 1 and 3 turn backwards */
        g_word = enc_word(last_cmd[enc] == 0x7FFD ? 0x0100 : g_angle);
        cmd = (uint16_t)(mosi << 8);
    } else {
        last_cmd[enc] = (uint16_t)(cmd | mosi);
    }
    uint8_t miso = g_byte_index == 0 ? (uint8_t)(g_word >> 8) : (uint8_t)g_word;
    g_byte_index ^= 1;
    return miso;
}

static uint16_t crc16(const uint8_t* d, int n) {
    uint16_t c = 0xFFFF;
    for (int i = 0; i < n; i++) {
        c ^= (uint16_t)(d[i] << 8);
        for (int b = 0; b < 8; b++)
            c = (c & 0x8000) ? (uint16_t)((c << 1) ^ 0x1021) : (uint16_t)(c << 1);
    }
    return c;
}

/* Frame id + payload into wire bytes (COBS + 0); returns the length. */
static int frame(uint8_t id, const uint8_t* p, int n, uint8_t* out) {
    uint8_t raw[64];
    raw[0] = id;
    memcpy(raw + 1, p, (size_t)n);
    uint16_t c = crc16(raw, n + 1);
    raw[n + 1] = (uint8_t)c;
    raw[n + 2] = (uint8_t)(c >> 8);
    int len = n + 3, o = 1, code_pos = 0, code = 1;
    for (int i = 0; i < len; i++) {
        if (raw[i] == 0) {
            out[code_pos] = (uint8_t)code;
            code_pos = o++;
            code = 1;
        } else {
            out[o++] = raw[i];
            code++;
        }
    }
    out[code_pos] = (uint8_t)code;
    out[o++] = 0;
    return o;
}

static void put_i32(uint8_t* p, int32_t v) {
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)((uint32_t)v >> (8 * i));
}

int main(int argc, char** argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: %s firmware.elf t2_addr rx_addr udre_addr\n", argv[0]);
        return 2;
    }
    isr_stat_t isr[3] = {
        {"TIMER2_COMPA", (uint32_t)strtoul(argv[2], 0, 0), 0, 0, 0, UINT64_MAX, 0, 0, 0, 0},
        {"USART0_RX", (uint32_t)strtoul(argv[3], 0, 0), 0, 0, 0, UINT64_MAX, 0, 0, 0, 0},
        {"USART0_UDRE", (uint32_t)strtoul(argv[4], 0, 0), 0, 0, 0, UINT64_MAX, 0, 0, 0, 0}};
    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (elf_read_firmware(argv[1], &fw) != 0) {
        fprintf(stderr, "cannot read %s\n", argv[1]);
        return 1;
    }
    avr_t* avr = avr_make_mcu_by_name("atmega2560");
    g_avr = avr;
    avr_init(avr);
    avr->frequency = 16000000;
    avr_load_firmware(avr, &fw);
    avr_register_io_write(avr, ADDR_GPIOR0, gpior0_write, NULL);
    avr_register_io_write(avr, ADDR_GPIOR1, window_write, &g_tick);
    avr_register_io_write(avr, ADDR_GPIOR2, window_write, &g_telem);
    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)AVR_UART_FLAG_STDIO;
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    if (sim_spi_install(avr, ADDR_SPDR, encoder_byte) != 0) return 1; /* not simavr's 100 us */
    sim_uart_install(avr, ADDR_UDR0); /* the chip's byte time, not simavr's 22 us */
    avr_irq_t* uart_in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            uart_out, NULL);

    uint8_t tx[512];
    int ntx = 0;
    uint8_t p[16];
    ntx += frame(0x01, p, 0, tx + ntx); /* HELLO */
    p[0] = 9;                           /* HEARTBEAT_MS = 1000 */
    put_i32(p + 1, 1000);
    ntx += frame(0x06, p, 5, tx + ntx);
    for (int i = 0; i < 4; i++) { /* ENC_OFFSET_Mi = 0: a blank EEPROM refuses closed loop */
        p[0] = (uint8_t)(15 + i);
        put_i32(p + 1, 0);
        ntx += frame(0x06, p, 5, tx + ntx);
    }
    for (int i = 0; i < 4; i++) put_i32(p + 4 * i, (i & 1) ? -74870 : 74870);
    ntx += frame(0x03, p, 16, tx + ntx); /* SET_SPEEDS 715 rpm */
    uint8_t beat[8]; /* HEARTBEAT, every 100 ms once the frames above are sent */
    const int nbeat = frame(0x02, p, 0, beat);
    int beat_sent = nbeat;
    uint64_t next_beat = 0;

    const char* prof_path = getenv("PROFILE");
    if (prof_path) g_profile = calloc(128 * 1024, sizeof *g_profile);
    const uint64_t end = 2 * 16000000ull;
    int sent = 0;
    uint64_t next_byte = 16000 * 20;
    while (avr->cycle < end) {
        if (sent == ntx && beat_sent == nbeat && avr->cycle >= next_beat) {
            beat_sent = 0;
            next_beat = avr->cycle + 16000 * 100;
        }
        if (avr->cycle >= next_byte && (sent < ntx || beat_sent < nbeat)) {
            avr_raise_irq(uart_in, sent < ntx ? tx[sent++] : beat[beat_sent++]);
            next_byte = avr->cycle + 400; /* 25 us: the host sends little */
        }
        uint32_t pc = avr->pc;
        for (int k = 0; k < 3; k++) {
            if (!isr[k].in && pc == isr[k].addr) {
                isr[k].in = 1;
                isr[k].start = avr->cycle;
                isr[k].in_step = g_mark_start != 0;
                isr[k].outside = avr->data[ADDR_GPIOR1] == 0;
            }
        }
        uint16_t op = (uint16_t)(avr->flash[pc] | (avr->flash[pc + 1] << 8));
        uint64_t c0 = avr->cycle;
        int state = avr_run(avr);
        uint16_t sp = (uint16_t)(avr->data[ADDR_SPL] | (avr->data[ADDR_SPH] << 8));
        if (sp < g_sp_min) g_sp_min = sp;
        if (g_profile && g_mark_start) g_profile[pc >> 1] += avr->cycle - c0;
        if (op == 0x9518) { /* reti */
            for (int k = 0; k < 3; k++) {
                if (isr[k].in) {
                    uint64_t d = avr->cycle - isr[k].start;
                    isr[k].in = 0;
                    isr[k].n++;
                    isr[k].sum += d;
                    if (d < isr[k].min) isr[k].min = d;
                    if (d > isr[k].max) isr[k].max = d;
                    if (isr[k].in_step) g_isr_this_step += d + 8;
                    if (g_first_mark) {
                        g_isr_all += d + 8;
                        if (isr[k].in_step) g_isr_in_step += d + 8;
                        if (isr[k].outside) g_isr_outside += d + 8;
                    }
                }
            }
        }
        if (state == cpu_Done || state == cpu_Crashed) {
            fprintf(stderr, "simavr stopped (state %d) at cycle %llu\n", state,
                    (unsigned long long)avr->cycle);
            return 1;
        }
    }
    if (g_steps <= 5) {
        fprintf(stderr, "no control step seen (GPIOR0 never toggled)\n");
        return 1;
    }
    uint64_t n = g_steps - 5;
    double mean = (double)g_sum / (double)n;
    printf(
        "control step (4 wheels, closed loop, 715 rpm, encoder reads included): n=%llu min=%llu "
        "mean=%.0f max=%llu cycles (%.1f us max at 16 MHz; mean %.1f %%, max "
        "%.1f %% of the %u-cycle tick)\n",
        (unsigned long long)n, (unsigned long long)g_min, mean, (unsigned long long)g_max,
        g_max / 16.0, 100.0 * mean / TICK_CYCLES, 100.0 * (double)g_max / TICK_CYCLES, TICK_CYCLES);
    printf("control step without the ISRs that preempted it: min=%llu mean=%.0f max=%llu cycles\n",
           (unsigned long long)g_pure_min, (double)g_pure_sum / (double)n,
           (unsigned long long)g_pure_max);
    if (n > 1) {
        printf("main loop: %.0f control steps per second (tick 1000 Hz)\n",
               (double)(n - 1) * 16e6 / (double)(g_last_mark - g_first_mark));
    }
    for (int k = 0; k < 3; k++) {
        if (isr[k].n == 0) {
            printf("ISR %-12s not entered\n", isr[k].name);
            continue;
        }
        printf("ISR %-12s n=%llu min=%llu max=%llu cycles (first instruction to reti; +8 entry)\n",
               isr[k].name, (unsigned long long)isr[k].n, (unsigned long long)isr[k].min,
               (unsigned long long)isr[k].max);
    }
    printf("UART TX: %llu bytes, %llu frames in %.1f s (telemetry at 500 Hz: about 1000)\n",
           (unsigned long long)g_tx_bytes, (unsigned long long)g_tx_frames, end / 16e6);
    printf("stack: deepest %u bytes below RAMEND (lowest SP 0x%04X over the run)\n",
           (unsigned)(RAMEND - g_sp_min), (unsigned)g_sp_min);
    if (g_telem.n > 0) {
        printf(
            "telemetry slice (GPIOR2: speeds, CRC, COBS or TX ring; ISRs inside included): n=%llu "
            "min=%llu mean=%.0f max=%llu cycles\n",
            (unsigned long long)g_telem.n, (unsigned long long)g_telem.min,
            (double)g_telem.sum / (double)g_telem.n, (unsigned long long)g_telem.max);
    }
    if (g_tick.n > 0) {
        double ticks = (double)(g_last_mark - g_first_mark) / TICK_CYCLES;
        double work = (double)g_tick.sum / (double)g_tick.n;
        printf(
            "tick work (GPIOR1: step, PWM, jobs, telemetry slices; ISRs inside included): n=%llu "
            "min=%llu mean=%.0f max=%llu cycles\n",
            (unsigned long long)g_tick.n, (unsigned long long)g_tick.min, work,
            (unsigned long long)g_tick.max);
        printf(
            "ISR load (+8 entry each): %.0f cycles per tick (%.1f %%), inside the step %.1f per "
            "step, outside the tick work %.0f per tick\n",
            g_isr_all / ticks, 100.0 * g_isr_all / ticks / TICK_CYCLES,
            (double)g_isr_in_step / (double)n, g_isr_outside / ticks);
        printf(
            "CPU load per tick (tick work + ISRs outside it): mean %.0f cycles = %.1f %% of the "
            "tick\n",
            work + g_isr_outside / ticks, 100.0 * (work + g_isr_outside / ticks) / TICK_CYCLES);
    }
    if (g_profile) {
        FILE* f = fopen(prof_path, "w");
        for (uint32_t i = 0; i < 128 * 1024; i++) {
            if (g_profile[i]) fprintf(f, "%x %llu\n", i * 2, (unsigned long long)g_profile[i]);
        }
        fclose(f);
    }
    return 0;
}
