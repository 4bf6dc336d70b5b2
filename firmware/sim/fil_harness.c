/*
 * fil_harness.c - firmware-in-the-loop harness for the wheel board (ATmega2560).
 *
 * Runs the real firmware ELF in simavr and closes the loop around it:
 *   - UART0 is exposed as a pseudo-terminal (uart_pty); its path is printed as "PTY <path>"
 *     and optionally linked at --pty-link.
 *   - Four AS5048A encoders are emulated on SPI, selected by PA4..PA7 (active low).
 *   - Four motors are modelled from the PWM compare registers of Timers 1/3/4/5 (fast PWM,
 *     TOP = ICRn; M0's phase C on Timer0 OC0B, TOP = OCR0A) and the enables PA0..PA3: applied
 *     voltage space vector (Clarke transform of the three duties around 50 %),
 *     torque = k_t |V| sin(angle(V) - p theta), J dw/dt = torque - b w.
 *   - Bytes from the pty reach UART0 at the line rate (one per byte time of UBRR0/U2X0, as
 *     sim_uart.h times the transmitter); a byte that finds the chip's 2-byte receive FIFO full
 *     is lost (data overrun), counted as rx_overrun.
 *   - Resets: the watchdog's reset restarts the firmware as on the chip; the harness then acts as
 *     the stock Mega bootloader (stk500v2) does on a watchdog reset: MCUSR cleared, application
 *     started (with --no-bootloader MCUSR is kept, as on a board flashed without one). A
 *     "RESET t_s=... wdrf=1" line reports each one.
 *   - --eeprom FILE loads the EEPROM from FILE (from address 0) before the firmware starts.
 *   - The control step is timed in CPU cycles between the firmware's writes GPIOR0 = 1 and
 *     GPIOR0 = 0; min/mean/max are printed periodically ("STATS ...") and at exit ("FINAL ...").
 *   - With --speed-period, a compact "SPEED t_us w0 w1 w2 w3 frames" line gives the model's true
 *     rotor speeds (rad/s) for a consumer such as the simulated rig's truth model.
 *
 * Simulated time is paced to wall-clock time unless --free is given. Commands on stdin
 * (one per line): "fault <motor> <mode>" (modes as --enc-fault), "clear <motor>", "load <motor>
 * <N*m>", "stats", "pwm", "tick-stop" (Timer2's clock off: the firmware's control tick stops),
 * "brown-out" (a reset with BORF set, as the brown-out detector gives), "vbus V" (the bridge
 * supply from now on), "hang" / "hang-cli" (the CPU jumps into a loop on itself, interrupts left as
 * they are or disabled: a firmware hung in a loop, or hung with interrupts off), "rx HEX" (bytes
 * queued for UART0 as if the host wrote them now), "rx-every PERIOD_US COUNT HEX" (the same every
 * PERIOD_US of simulated time, COUNT times), "quit". The harness never calls uart_pty_stop(): it
 * hangs in pthread_join in simavr 1.6.
 */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <simavr/avr_eeprom.h>
#include <simavr/avr_extint.h>
#include <simavr/avr_ioport.h>
#include <simavr/avr_spi.h>
#include <simavr/avr_uart.h>
#include <simavr/parts/uart_pty.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_io.h>
#include <simavr/sim_irq.h>

#include "sim_spi.h"
#include "sim_rx.h"
#include "sim_uart.h"

/* ATmega2560 data-space addresses (avr-libc iomxx0_1.h, I/O address + 0x20). */
enum {
    ADDR_PORTA = 0x22,
    ADDR_DDRA = 0x21,
    ADDR_GPIOR0 = 0x3E,
    ADDR_SPDR = 0x4E,
    ADDR_UDR0 = 0xC6,
    ADDR_MCUSR = 0x54,
    ADDR_TCCR2B = 0xB1,
};

#define N_MOTORS 4
#define TWO_PI 6.283185307179586
#define ENC_COUNTS 16384

/* One phase output: the timer's TCCRnA/TCCRnB, its TOP register (ICRn in mode 14, OCR0A in
   Timer0's mode 7), its compare register, the channel (0..2 = A..C, for the COM bits) and whether
   the timer is 16-bit (the registers are then 16-bit, low byte first). */
typedef struct {
    uint16_t tccra, tccrb, top, ocr;
    uint8_t ch, wide;
} phase_regs_t;

#define PH16(n, c) \
    { 0x80 + 16 * (n), 0x81 + 16 * (n), 0x86 + 16 * (n), 0x88 + 16 * (n) + 2 * (c), c, 1 }
#define PH16_T5(c) \
    { 0x120, 0x121, 0x126, 0x128 + 2 * (c), c, 1 }
static const phase_regs_t k_phases[N_MOTORS][3] = {
    /* M0: Timer1 OC1A, OC1B; phase C on Timer0 OC0B (OC1C is PB7, the LED the bootloader drives) */
    {PH16(0, 0), PH16(0, 1), {0x44, 0x45, 0x47, 0x48, 1, 0}},
    {PH16(1, 0), PH16(1, 1), PH16(1, 2)}, /* M1: Timer3 (0x90..) */
    {PH16(2, 0), PH16(2, 1), PH16(2, 2)}, /* M2: Timer4 (0xA0..) */
    {PH16_T5(0), PH16_T5(1), PH16_T5(2)}, /* M3: Timer5 */
};
#undef PH16
#undef PH16_T5

typedef enum {
    ENC_OK = 0,
    ENC_FAULT_ERRFLAG, /* answers with the error flag (bit 14) set */
    ENC_FAULT_HIGH,    /* no answer, MISO pulled high: reads 0xFFFF */
    ENC_FAULT_LOW,     /* no answer, MISO stuck low: reads 0x0000 */
    ENC_FAULT_PARITY,  /* angle with a wrong parity bit */
    ENC_FAULT_FROZEN,  /* valid words, the angle frozen where the rotor was when injected */
    ENC_FAULT_WEAK,    /* diagnostics register: magnet too weak (COMP_HIGH, AGC 255) */
} enc_fault_t;

static const char* const k_fault_names[] = {"none",   "error",  "high", "low",
                                            "parity", "frozen", "weak"};

typedef struct {
    /* motor model */
    double theta_rad; /* mechanical rotor angle */
    double omega_rad_s;
    double load_nm; /* extra load torque (opposes positive rotation), set from stdin */
    double v_alpha, v_beta;
    double v_q, v_d; /* applied vector in rotor coordinates (q: torque-producing), V */
    int enabled;
    /* AS5048A emulation */
    int selected;       /* chip select currently low */
    int byte_in_frame;  /* bytes exchanged since CS fell */
    uint16_t rx_word;   /* command being shifted in */
    uint16_t tx_word;   /* answer being shifted out */
    uint16_t last_cmd;  /* command latched at the last complete frame */
    int error_flag;     /* sticky error flag as in the chip's error register */
    volatile int fault; /* enc_fault_t, may be changed from the stdin thread */
    uint16_t frozen;    /* the angle code of ENC_FAULT_FROZEN */
} motor_t;

typedef struct {
    double k_t_nm_per_v;
    double k_e_vs_rad;
    double j_kgm2;
    double b_nms;
    double vbus_v;
    double elec_offset_rad;
    int pole_pairs;
    uint32_t model_cycles;
    double enc_noise_counts; /* rms of the Gaussian noise on every angle read (--enc-noise) */
    double cogging_nm;       /* amplitude of the cogging torque (--cogging) */
    int cogging_per_rev;     /* its periods per mechanical turn */
} params_t;

static params_t g_par = {
    /* GB54-1 gimbal motor driving a 100 g rotor wheel: defaults are deliberately round numbers
       of the right order (see docs/fil.md); every one is an option. */
    .k_t_nm_per_v = 0.01,
    .k_e_vs_rad = 0.02,
    .j_kgm2 = 1.8e-4,
    .b_nms = 2.0e-5,
    .vbus_v = 12.0,
    /* 0: the rotor holds where the applied vector points when pole_pairs * encoder angle equals
       the vector angle, the convention of the wheel firmware (commut.h) with ENC_OFFSET = 0 */
    .elec_offset_rad = 0.0,
    .pole_pairs = 7,
    .model_cycles = 1000,
    /* 12 slots and 14 poles (7 pole pairs): the cogging repeats lcm(12, 14) = 84 times a turn */
    .cogging_per_rev = 84,
};

/* Noise of the angle reads: xorshift64 and Box-Muller, seeded (--seed) so a run repeats. */
static uint64_t g_rng = 0x9E3779B97F4A7C15ull;
static double rng_uniform(void) {
    g_rng ^= g_rng << 13;
    g_rng ^= g_rng >> 7;
    g_rng ^= g_rng << 17;
    return ((double)(g_rng >> 11) + 0.5) / 9007199254740992.0; /* (0, 1) */
}
static double rng_gauss(void) {
    return sqrt(-2.0 * log(rng_uniform())) * cos(TWO_PI * rng_uniform());
}

static motor_t g_mot[N_MOTORS];
static avr_t* g_avr;
static uart_pty_t g_pty;

/* control-step cycle statistics */
typedef struct {
    uint64_t n, sum, min, max, overruns;
} cyc_stats_t;
static cyc_stats_t g_cyc_total, g_cyc_window;
static avr_cycle_count_t g_step_start;
static int g_step_open;
static uint64_t g_tick_cycles = 16000;

static volatile sig_atomic_t g_stop;
static volatile int g_stats_request;
static volatile int g_pwm_request;
static double g_stats_period_s = 1.0;
static double g_rate = 1.0; /* simulated seconds per wall second; 0 = free-running */
static double g_wall_t0;
static double g_uart_wait_s;    /* wall time the simulation waited for uart_pty (see below) */
static double g_speed_period_s; /* simulated seconds between SPEED lines; 0 = none */
static double g_uart_wait_max_s = 2.0; /* longest back-pressure wait for the pty reader */
static int g_uart_no_reader;           /* a wait timed out: drop output until the FIFO drains */
static unsigned long long g_frames;    /* 0x00 bytes (COBS frame delimiters) the UART sent */
static volatile int g_tick_stop_request;
static volatile int g_hang_request; /* 1: hang, 2: hang with interrupts disabled */
static volatile int g_brown_out_request;
static int g_keep_mcusr;            /* --no-bootloader */
static unsigned long long g_resets; /* resets after power-on (watchdog) */

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double sim_time_s(void) {
    return (double)g_avr->cycle / (double)g_avr->frequency;
}

static uint16_t read16(uint16_t addr) {
    return (uint16_t)(g_avr->data[addr] | ((uint16_t)g_avr->data[addr + 1] << 8));
}

/* ---------------------------------------------------------------- cycle counting (GPIOR0) */

static void cyc_add(cyc_stats_t* s, uint64_t c) {
    if (s->n == 0 || c < s->min) s->min = c;
    if (c > s->max) s->max = c;
    s->sum += c;
    s->n++;
    if (c > g_tick_cycles) s->overruns++;
}

static void gpior0_write(avr_t* avr, avr_io_addr_t addr, uint8_t v, void* param) {
    (void)param;
    avr->data[addr] = v; /* the register must still hold what the firmware wrote */
    if (v == 1) {
        g_step_start = avr->cycle;
        g_step_open = 1;
    } else if (v == 0 && g_step_open) {
        uint64_t c = avr->cycle - g_step_start;
        cyc_add(&g_cyc_total, c);
        cyc_add(&g_cyc_window, c);
        g_step_open = 0;
    }
}

/* ---------------------------------------------------------------- AS5048A emulation */

static uint16_t with_even_parity(uint16_t w15) {
    uint16_t x = w15 & 0x7FFF;
    int ones = __builtin_popcount(x);
    return (uint16_t)(x | ((ones & 1) ? 0x8000 : 0));
}

static uint16_t encoder_angle_code(const motor_t* m) {
    double turns = m->theta_rad / TWO_PI;
    turns -= floor(turns);
    return (uint16_t)((int)(turns * ENC_COUNTS) & 0x3FFF);
}

/* The angle as the sensor reports it: with --enc-noise, plus Gaussian noise of that rms. */
static uint16_t encoder_read_code(const motor_t* m) {
    if (g_par.enc_noise_counts <= 0.0) return encoder_angle_code(m);
    double turns = m->theta_rad / TWO_PI;
    double code = (turns - floor(turns)) * ENC_COUNTS + g_par.enc_noise_counts * rng_gauss();
    return (uint16_t)((int)floor(code + 2.0 * ENC_COUNTS) & 0x3FFF);
}

/* Answer of the frame that starts now, given the command latched in the previous frame. */
static uint16_t encoder_answer(motor_t* m) {
    switch ((enc_fault_t)m->fault) {
        case ENC_FAULT_HIGH:
            return 0xFFFF;
        case ENC_FAULT_LOW:
            return 0x0000;
        default:
            break;
    }
    uint16_t cmd = m->last_cmd;
    uint16_t data;
    if (cmd == 0x0000) {
        data = 0; /* NOP */
    } else if ((cmd & 0x3FFF) == 0x3FFF && (cmd & 0x4000)) {
        data = m->fault == ENC_FAULT_FROZEN ? m->frozen : encoder_read_code(m);
    } else if ((cmd & 0x3FFF) == 0x0001 && (cmd & 0x4000)) {
        data = m->error_flag ? 0x0001 : 0; /* clear error flag register: reading clears it */
        m->error_flag = 0;
    } else if ((cmd & 0x3FFF) == 0x3FFD && (cmd & 0x4000)) {
        /* diagnostics: OCF (offset compensation finished), no COF/COMP; or weak: COMP_HIGH */
        data = m->fault == ENC_FAULT_WEAK ? 0x09FF : 0x0100;
    } else {
        data = 0;
        m->error_flag = 1; /* invalid command */
    }
    if (m->fault == ENC_FAULT_ERRFLAG) m->error_flag = 1;
    uint16_t w = (uint16_t)((data & 0x3FFF) | (m->error_flag ? 0x4000 : 0));
    w = with_even_parity(w);
    if (m->fault == ENC_FAULT_PARITY) w ^= 0x8000;
    return w;
}

static void chip_select_changed(struct avr_irq_t* irq, uint32_t value, void* param) {
    (void)irq;
    motor_t* m = (motor_t*)param;
    int sel = (value == 0);
    if (sel && !m->selected) {
        m->byte_in_frame = 0;
        m->rx_word = 0;
        m->tx_word = encoder_answer(m);
    } else if (!sel && m->selected) {
        if (m->byte_in_frame == 2) {
            /* A command with a wrong parity sets the chip's error flag. */
            if (with_even_parity(m->rx_word) != m->rx_word) m->error_flag = 1;
            m->last_cmd = m->rx_word;
        }
    }
    m->selected = sel;
}

/* One byte on the bus: every selected slave shifts out its byte (wired-AND of MISO). */
static uint8_t slaves_exchange(uint8_t mosi) {
    uint8_t miso = 0xFF;
    for (int i = 0; i < N_MOTORS; i++) {
        motor_t* m = &g_mot[i];
        if (!m->selected) continue;
        uint8_t out = 0xFF;
        if (m->byte_in_frame == 0) {
            out = (uint8_t)(m->tx_word >> 8);
            m->rx_word = (uint16_t)(mosi << 8);
        } else if (m->byte_in_frame == 1) {
            out = (uint8_t)(m->tx_word & 0xFF);
            m->rx_word |= mosi;
        }
        m->byte_in_frame++;
        miso &= out;
    }
    return miso;
}

/* ---------------------------------------------------------------- PWM timers */

/*
 * simavr 1.6 schedules a cycle-timer event for every overflow and compare match of a running
 * timer and looks the output pin up through avr_ioctl() each time: four timers at 20 kHz cost
 * more host time than the whole CPU (measured: a busy loop ran 13x real time with no PWM timer,
 * 1.2x with four). The motor model reads OCRnx/ICRn itself, so by default the control registers
 * of Timers 1/3/4/5 are plain storage and those timers never start. TCNTn, their interrupts and
 * OC pin levels are then not simulated (warned about if the firmware enables such an
 * interrupt); --sim-pwm-timers restores simavr's own handling.
 */
/* TIMSKn of the PWM timers 1, 3, 4, 5 and 0 */
static const uint16_t k_timsk[] = {0x6F, 0x71, 0x72, 0x73, 0x6E};
static int g_sim_pwm_timers;
static int g_timsk_warned;

static void plain_store(avr_t* avr, avr_io_addr_t addr, uint8_t v, void* param) {
    (void)param;
    avr->data[addr] = v;
}

static void detach_range(avr_t* avr, uint16_t first, uint16_t last) {
    for (uint16_t a = first; a <= last; a++) {
        avr->io[AVR_DATA_TO_IO(a)].w.c = plain_store;
        avr->io[AVR_DATA_TO_IO(a)].w.param = NULL;
    }
}

static void detach_pwm_timers(avr_t* avr) {
    /* TCCRnA/B/C, TCNTn, ICRn, OCRnA/B/C are consecutive; an OCR write alone would make simavr
       reconfigure, and so start, the timer from the stored TCCRnB. Timer0: TCCR0A..OCR0B. */
    for (int i = 0; i < N_MOTORS; i++) {
        const phase_regs_t* a = &k_phases[i][0]; /* phase A: always on the motor's 16-bit timer */
        detach_range(avr, a->tccra, a->tccra + 0x0D); /* TCCRnA .. OCRnC high byte */
    }
    const phase_regs_t* t0 = &k_phases[0][2];
    detach_range(avr, t0->tccra, t0->ocr);
}

static void check_timer_interrupts(void) {
    if (g_sim_pwm_timers || g_timsk_warned) return;
    for (size_t i = 0; i < sizeof(k_timsk) / sizeof(k_timsk[0]); i++) {
        if (g_avr->data[k_timsk[i]] != 0) {
            printf(
                "WARN firmware enabled TIMSK 0x%02x = 0x%02x on a PWM timer; its interrupts "
                "are not simulated without --sim-pwm-timers\n",
                k_timsk[i], g_avr->data[k_timsk[i]]);
            g_timsk_warned = 1;
        }
    }
}

/* ---------------------------------------------------------------- motor model */

static uint16_t phase_reg(const phase_regs_t* p, uint16_t addr) {
    return p->wide ? read16(addr) : g_avr->data[addr];
}

/* TOP of the phase's timer in a fast PWM mode, 0 otherwise (no drive: phase-correct modes do not
   run in simavr). */
static uint16_t pwm_top(const phase_regs_t* p) {
    uint8_t a = g_avr->data[p->tccra], b = g_avr->data[p->tccrb];
    if (!p->wide) { /* Timer0: WGM02 in TCCR0B bit 3 */
        int wgm = (a & 3) | ((b >> 1) & 4);
        return wgm == 3 ? 0xFF : wgm == 7 ? g_avr->data[p->top] : 0;
    }
    int wgm = (a & 3) | ((b >> 1) & 0x0C);
    switch (wgm) {
        case 5:
            return 0xFF;
        case 6:
            return 0x1FF;
        case 7:
            return 0x3FF;
        case 14:
            return read16(p->top);
        case 15:
            return read16(p->top + 2); /* OCRnA */
        default:
            return 0;
    }
}

/* Duty of a fast PWM output as on the chip: high for OCR + 1 of TOP + 1 counts (non-inverting;
   COM = 3 inverts; a disconnected output counts as 50 %, a floating phase); -1 if the timer is
   not in a fast PWM mode. */
static double phase_duty(const phase_regs_t* p) {
    uint16_t top = pwm_top(p);
    if (top == 0) return -1.0;
    uint8_t com = (uint8_t)((g_avr->data[p->tccra] >> (6 - 2 * p->ch)) & 3);
    double d = ((double)phase_reg(p, p->ocr) + 1.0) / ((double)top + 1.0);
    if (d > 1.0) d = 1.0;
    if (com == 3) d = 1.0 - d;
    if (com < 2) d = 0.5;
    return d;
}

static void motor_voltage(int i, motor_t* m) {
    uint8_t porta = g_avr->data[ADDR_PORTA] & g_avr->data[ADDR_DDRA];
    double v[3];
    int running = 1;
    for (int k = 0; k < 3; k++) {
        double d = phase_duty(&k_phases[i][k]);
        if (d < 0) running = 0;
        v[k] = (d - 0.5) * g_par.vbus_v;
    }
    m->enabled = ((porta >> i) & 1) && running;
    if (!m->enabled) {
        m->v_alpha = m->v_beta = 0.0;
        return;
    }
    /* amplitude-invariant Clarke transform: the common mode drops out */
    m->v_alpha = (2.0 / 3.0) * (v[0] - 0.5 * v[1] - 0.5 * v[2]);
    m->v_beta = (2.0 / 3.0) * (0.8660254037844386 * (v[1] - v[2]));
}

static void motor_step(motor_t* m, double dt) {
    double e = g_par.pole_pairs * m->theta_rad + g_par.elec_offset_rad;
    /* k_t (|V| sin(angle(V) - e) - k_e w): the quadrature voltage, written without atan2,
       minus the back-EMF, drives the (resistive) winding current; k_t = K_torque / R */
    m->v_q = m->v_beta * cos(e) - m->v_alpha * sin(e);
    m->v_d = m->v_alpha * cos(e) + m->v_beta * sin(e);
    double torque =
        m->enabled ? g_par.k_t_nm_per_v * (m->v_q - g_par.k_e_vs_rad * m->omega_rad_s) : 0;
    double load = m->load_nm;
    if (m->omega_rad_s < 0) load = -load;
    /* cogging: a torque periodic in the rotor angle, drive or no drive */
    load += g_par.cogging_nm * sin(g_par.cogging_per_rev * m->theta_rad);
    double acc = (torque - g_par.b_nms * m->omega_rad_s - load) / g_par.j_kgm2;
    m->omega_rad_s += acc * dt; /* semi-implicit Euler */
    m->theta_rad += m->omega_rad_s * dt;
    if (m->theta_rad > 1e6 || m->theta_rad < -1e6) m->theta_rad = fmod(m->theta_rad, TWO_PI);
}

static double rpm(const motor_t* m) {
    return m->omega_rad_s * 60.0 / TWO_PI;
}

/* ---------------------------------------------------------------- stats output */

static void print_stats(const char* tag, const cyc_stats_t* s) {
    double mean = s->n ? (double)s->sum / (double)s->n : 0.0;
    double wall = now_s() - g_wall_t0;
    double t = sim_time_s();
    printf(
        "%s t_s=%.3f wall_s=%.3f rt=%.3f steps=%llu cyc_min=%llu cyc_mean=%.1f cyc_max=%llu "
        "load_pct=%.2f overruns=%llu rpm=%.2f,%.2f,%.2f,%.2f vq=%.2f,%.2f,%.2f,%.2f "
        "vd=%.2f,%.2f,%.2f,%.2f faults=%s,%s,%s,%s uart_wait_s=%.3f resets=%llu rx_overrun=%llu\n",
        tag, t, wall, wall > 0 ? t / wall : 0.0, (unsigned long long)s->n,
        (unsigned long long)s->min, mean, (unsigned long long)s->max,
        100.0 * (double)s->max / (double)g_tick_cycles, (unsigned long long)s->overruns,
        rpm(&g_mot[0]), rpm(&g_mot[1]), rpm(&g_mot[2]), rpm(&g_mot[3]), g_mot[0].v_q, g_mot[1].v_q,
        g_mot[2].v_q, g_mot[3].v_q, g_mot[0].v_d, g_mot[1].v_d, g_mot[2].v_d, g_mot[3].v_d,
        k_fault_names[g_mot[0].fault], k_fault_names[g_mot[1].fault], k_fault_names[g_mot[2].fault],
        k_fault_names[g_mot[3].fault], g_uart_wait_s, g_resets, sim_rx_overrun);
    fflush(stdout);
}

/* "OK pwm": per motor enable, TOP and compare value of each phase (TOP/OCR), rotor angle, speed
   and the encoder's last answer */
static void print_pwm(void) {
    printf("OK pwm");
    for (int i = 0; i < N_MOTORS; i++) {
        printf(" m%d=%d", i, g_mot[i].enabled);
        for (int k = 0; k < 3; k++) {
            const phase_regs_t* p = &k_phases[i][k];
            printf("/%u:%u", pwm_top(p), phase_reg(p, p->ocr));
        }
        printf("/%.4f/%.3f/%04x", g_mot[i].theta_rad, g_mot[i].omega_rad_s, g_mot[i].tx_word);
    }
    printf("\n");
    fflush(stdout);
}

/* "SPEED t_us w0 w1 w2 w3 frames": simulated time, the motor model's true rotor speeds in
   rad/s and the frames the firmware has sent so far (counted at their 0x00 delimiters) */
static void print_speed(void) {
    printf("SPEED %llu %.4f %.4f %.4f %.4f %llu\n",
           (unsigned long long)(g_avr->cycle * 1000000ULL / g_avr->frequency), g_mot[0].omega_rad_s,
           g_mot[1].omega_rad_s, g_mot[2].omega_rad_s, g_mot[3].omega_rad_s, g_frames);
}

static void uart_byte_out(struct avr_irq_t* irq, uint32_t value, void* param) {
    (void)irq;
    (void)param;
    if ((value & 0xFF) == 0) g_frames++;
}

/* ---------------------------------------------------------------- periodic work */

static avr_cycle_count_t model_timer(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)param;
    double dt = (double)g_par.model_cycles / (double)avr->frequency;
    for (int i = 0; i < N_MOTORS; i++) {
        motor_voltage(i, &g_mot[i]);
        motor_step(&g_mot[i], dt);
    }
    check_timer_interrupts();
    return when + g_par.model_cycles;
}

/*
 * uart_pty (simavr 1.6) moves firmware output through a 512-byte FIFO to the pty from its own
 * thread and silently drops bytes when that FIFO is full: a busy host (two cores, a test runner,
 * builds) lost telemetry bytes that way. Back-pressure instead: while the FIFO is more than half
 * full the simulation waits for the pty thread, as a UART would wait for a slow reader's USB
 * bridge. Checked every simulated millisecond (19 bytes of telemetry per ms at 1 Mbaud and 500 Hz).
 */
static unsigned uart_out_fill(void) {
    return (unsigned)(g_pty.pty.in.write - g_pty.pty.in.read) & (uart_pty_fifo_fifo_size - 1);
}

/* A wait that reaches --uart-wait-max means nobody reads the pty (the simulated rig serves it
   before a host opens it): the firmware's output is then lost, as on a UART nobody listens to,
   until a reader empties the FIFO again. */
static void uart_backpressure(void) {
    unsigned fill = uart_out_fill();
    if (g_uart_no_reader && fill <= uart_pty_fifo_fifo_size / 8) g_uart_no_reader = 0;
    if (fill < uart_pty_fifo_fifo_size / 2 || g_uart_no_reader) return;
    double t0 = now_s();
    struct timespec ts = {0, 200000};
    while (uart_out_fill() > uart_pty_fifo_fifo_size / 8 && now_s() - t0 < g_uart_wait_max_s) {
        nanosleep(&ts, NULL);
    }
    g_uart_no_reader = uart_out_fill() > uart_pty_fifo_fifo_size / 8;
    g_uart_wait_s += now_s() - t0;
}

static avr_cycle_count_t pace_timer(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)param;
    uart_backpressure();
    if (g_rate > 0) {
        double ahead = sim_time_s() / g_rate - (now_s() - g_wall_t0);
        if (ahead > 0.0005) {
            struct timespec ts = {0, (long)(ahead * 1e9)};
            nanosleep(&ts, NULL);
        }
    }
    return when + avr->frequency / 1000; /* every simulated millisecond */
}

static avr_cycle_count_t speed_timer(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)param;
    print_speed();
    return when + (avr_cycle_count_t)(g_speed_period_s * avr->frequency);
}

static avr_cycle_count_t stats_timer(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)param;
    print_stats("STATS", &g_cyc_window);
    memset(&g_cyc_window, 0, sizeof(g_cyc_window));
    return when + (avr_cycle_count_t)(g_stats_period_s * avr->frequency);
}

/* ---------------------------------------------------------------- PC sampling profile */

/* --profile FILE: the program counter is sampled every 997 cycles (prime, so the samples do not
   lock to the 16,000-cycle tick) while GPIOR0 = 1; FILE gets "byte_address count" lines, to be
   mapped to functions with avr-addr2line -f (firmware/sim/profile.sh). */
#define PROFILE_PERIOD 997
static uint32_t* g_profile;
static const char* g_profile_path;

static avr_cycle_count_t profile_timer(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)param;
    if (g_step_open && avr->pc / 2 < 0x20000) g_profile[avr->pc / 2]++;
    return when + PROFILE_PERIOD;
}

static void write_profile(void) {
    if (!g_profile) return;
    FILE* f = fopen(g_profile_path, "w");
    if (!f) {
        fprintf(stderr, "fil_harness: cannot write %s: %s\n", g_profile_path, strerror(errno));
        return;
    }
    for (uint32_t i = 0; i < 0x20000; i++) {
        if (g_profile[i]) fprintf(f, "0x%05x %u\n", (unsigned)(i * 2), (unsigned)g_profile[i]);
    }
    fclose(f);
}

/* ---------------------------------------------------------------- ISR costs */

/* --isr-stats: avr_run() executes one instruction, so the main loop sees the PC land on a vector
   (byte address 4 * n, n >= 1) when simavr services an interrupt. The cost of one ISR is counted
   from there until the stack pointer is back above the pushed 3-byte return address (after
   RETI): vector JMP, prologue, body, epilogue and RETI; not the 5-cycle response itself. */
#define N_VECTORS 57
#define ADDR_SPL 0x5D
static int g_isr_stats;
static cyc_stats_t g_isr[N_VECTORS];
static int g_isr_vec;
static uint16_t g_isr_sp;
static avr_cycle_count_t g_isr_start;

static uint16_t stack_pointer(void) {
    return read16(ADDR_SPL);
}

static void isr_track(void) {
    uint32_t pc = g_avr->pc;
    if (g_isr_vec) {
        if (stack_pointer() == g_isr_sp) {
            uint64_t c = g_avr->cycle - g_isr_start;
            cyc_add(&g_isr[g_isr_vec], c);
            g_isr_vec = 0;
        }
        return;
    }
    if (pc != 0 && pc < 4 * N_VECTORS && pc % 4 == 0) {
        g_isr_vec = (int)(pc / 4);
        g_isr_sp = (uint16_t)(stack_pointer() + 3);
        g_isr_start = g_avr->cycle;
    }
}

static void print_isr_stats(void) {
    for (int v = 1; v < N_VECTORS; v++) {
        const cyc_stats_t* s = &g_isr[v];
        if (!s->n) continue;
        printf("ISR vector=%d n=%llu cyc_min=%llu cyc_mean=%.1f cyc_max=%llu\n", v,
               (unsigned long long)s->n, (unsigned long long)s->min, (double)s->sum / (double)s->n,
               (unsigned long long)s->max);
    }
}

/* ---------------------------------------------------------------- timers and resets */

static void register_timers(avr_t* avr) {
    avr_cycle_timer_register(avr, g_par.model_cycles, model_timer, NULL);
    avr_cycle_timer_register(avr, avr->frequency / 1000, pace_timer, NULL);
    sim_uart_install(avr, ADDR_UDR0); /* the chip's UART byte time (sim_uart.h) */
    if (g_stats_period_s > 0) {
        avr_cycle_timer_register(avr, (avr_cycle_count_t)(g_stats_period_s * avr->frequency),
                                 stats_timer, NULL);
    }
    if (g_speed_period_s > 0) {
        avr_cycle_timer_register(avr, (avr_cycle_count_t)(g_speed_period_s * avr->frequency),
                                 speed_timer, NULL);
    }
    if (g_profile) avr_cycle_timer_register(avr, PROFILE_PERIOD, profile_timer, NULL);
    sim_rx_reset(avr);
}

/* The stock bootloader on a watchdog reset: MCUSR read and cleared, the application started at
   once. Run one cycle after the reset, when simavr's watchdog has set WDRF. */
static avr_cycle_count_t bootloader_timer(avr_t* avr, avr_cycle_count_t when, void* param) {
    (void)when;
    (void)param;
    uint8_t mcusr = avr->data[ADDR_MCUSR];
    if (!g_keep_mcusr) avr->data[ADDR_MCUSR] = 0;
    printf("RESET t_s=%.6f wdrf=%d borf=%d\n", sim_time_s(), (mcusr >> 3) & 1, (mcusr >> 2) & 1);
    fflush(stdout);
    return 0;
}

/* avr_reset() (the watchdog's) drops every cycle timer and clears the I/O registers; SRAM, the
   EEPROM and the pins' IRQ hooks stay. Registered after avr_init(), so called on resets only. */
static void on_reset(avr_io_t* io) {
    avr_t* avr = io->avr;
    g_resets++;
    g_step_open = 0;
    register_timers(avr);
    avr_cycle_timer_register(avr, 1, bootloader_timer, NULL);
}

static avr_io_t g_reset_io = {.kind = "fil-reset", .reset = on_reset};

/* A hung firmware: the CPU loops on one instruction (rjmp .-2 in the last flash word, which the
   application never reaches: the bootloader's area), with interrupts disabled for "hang-cli". */
#define HANG_PC 0x3FFFEu
static void hang_cpu(int interrupts_off) {
    g_avr->flash[HANG_PC] = 0xFF; /* rjmp .-2: 0xCFFF, little-endian */
    g_avr->flash[HANG_PC + 1] = 0xCF;
    g_avr->pc = HANG_PC;
    /* Set either way: a command that lands inside an interrupt (I cleared by its entry) would
       otherwise leave a "hang" with interrupts off. */
    g_avr->sreg[S_I] = interrupts_off ? 0 : 1;
    printf("OK hang t_s=%.6f interrupts=%s\n", sim_time_s(), interrupts_off ? "off" : "on");
    fflush(stdout);
}

/* Timer2's clock off through its register's write handler (simavr then stops the timer), as a
   firmware stuck outside its control tick would leave it. */
static void stop_tick_timer(void) {
    avr_io_addr_t a = AVR_DATA_TO_IO(ADDR_TCCR2B);
    if (g_avr->io[a].w.c) {
        g_avr->io[a].w.c(g_avr, ADDR_TCCR2B, 0, g_avr->io[a].w.param);
    } else {
        g_avr->data[ADDR_TCCR2B] = 0;
    }
    printf("OK tick-stop t_s=%.6f\n", sim_time_s());
    fflush(stdout);
}

/* ---------------------------------------------------------------- stdin commands */

static int parse_fault(const char* s) {
    for (int i = 0; i < (int)(sizeof(k_fault_names) / sizeof(k_fault_names[0])); i++) {
        if (strcmp(s, k_fault_names[i]) == 0) return i;
    }
    return -1;
}

static void* stdin_thread(void* arg) {
    (void)arg;
    char line[768]; /* "rx" lines carry up to 256 bytes in hex */
    while (fgets(line, sizeof(line), stdin)) {
        char cmd[16] = "", mode[16] = "";
        int motor = -1;
        double value = 0.0;
        int n = sscanf(line, "%15s %d %15s", cmd, &motor, mode);
        int motor_ok = motor >= 0 && motor < N_MOTORS;
        if (n >= 1 && strcmp(cmd, "quit") == 0) {
            g_stop = 1;
        } else if (n >= 1 && strcmp(cmd, "pwm") == 0) {
            g_pwm_request = 1;
        } else if (n >= 1 && strcmp(cmd, "rx") == 0) {
            char hex[600] = "";
            if (sscanf(line, "%*s %599s", hex) != 1 || !sim_rx_inject_request(hex, 0, 0)) {
                printf("ERR rx wants up to 256 bytes in hex: %s", line);
            }
        } else if (n >= 1 && strcmp(cmd, "rx-every") == 0) {
            char hex[600] = "";
            double period_us = 0;
            unsigned count = 0;
            if (sscanf(line, "%*s %lf %u %599s", &period_us, &count, hex) != 3 || count == 0 ||
                !sim_rx_inject_request(hex, period_us, count)) {
                printf("ERR rx-every wants PERIOD_US COUNT HEX: %s", line);
            }
        } else if (n >= 1 && strcmp(cmd, "tick-stop") == 0) {
            g_tick_stop_request = 1;
        } else if (n >= 1 && strcmp(cmd, "vbus") == 0 && sscanf(line, "%*s %lf", &value) == 1 &&
                   value > 0.0) {
            g_par.vbus_v = value; /* a supply sag (or its end), from now on */
            printf("OK vbus %g t_s=%.6f\n", value, sim_time_s());
        } else if (n >= 1 && strcmp(cmd, "brown-out") == 0) {
            g_brown_out_request = 1;
        } else if (n >= 1 && strcmp(cmd, "hang") == 0) {
            g_hang_request = 1;
        } else if (n >= 1 && strcmp(cmd, "hang-cli") == 0) {
            g_hang_request = 2;
        } else if (n >= 1 && strcmp(cmd, "stats") == 0) {
            g_stats_request = 1;
        } else if (n == 3 && strcmp(cmd, "fault") == 0 && motor_ok && parse_fault(mode) >= 0) {
            g_mot[motor].frozen = encoder_angle_code(&g_mot[motor]);
            g_mot[motor].fault = parse_fault(mode);
            printf("OK fault %d %s\n", motor, mode);
        } else if (n == 2 && strcmp(cmd, "clear") == 0 && motor_ok) {
            g_mot[motor].fault = ENC_OK;
            printf("OK clear %d\n", motor);
        } else if (n == 3 && strcmp(cmd, "load") == 0 && motor_ok &&
                   sscanf(mode, "%lf", &value) == 1) {
            g_mot[motor].load_nm = value;
            printf("OK load %d %g\n", motor, value);
        } else {
            printf("ERR unknown command: %s", line);
        }
        fflush(stdout);
    }
    return NULL; /* stdin closed: keep running */
}

static void on_signal(int sig) {
    (void)sig;
    g_stop = 1;
}

static void on_usr1(int sig) {
    (void)sig;
    g_stats_request = 1;
}

/* The pacing is ours: never let simavr usleep() on CPU sleep. */
static void no_sleep(avr_t* avr, avr_cycle_count_t how_long) {
    (void)avr;
    (void)how_long;
}

/* ---------------------------------------------------------------- set-up */

static void usage(const char* prog) {
    fprintf(stderr,
            "usage: %s [options] firmware.elf\n"
            "  -t, --time S           run S simulated seconds (default: until killed / quit)\n"
            "  -f, --free             free-running (default: paced to wall-clock time)\n"
            "  -r, --rate X           pace to X simulated seconds per wall second (default 1)\n"
            "  -l, --pty-link PATH    symlink PATH to the UART0 pseudo-terminal\n"
            "  -s, --stats-period S   simulated seconds between STATS lines (default 1, 0 = off)\n"
            "      --speed-period S   simulated seconds between SPEED lines (default 0 = off)\n"
            "      --uart-wait-max S  longest wall wait for the pty reader when the UART FIFO is\n"
            "                         full; then output is lost until it drains (default 2)\n"
            "  -e, --enc-fault M:MODE encoder M (0..3) fault from start: "
            "error|high|low|parity|frozen|weak\n"
            "      --kt NM_PER_V      torque per volt of applied vector (default %g)\n"
            "      --ke V_S_PER_RAD   back-EMF per rad/s, active while enabled (default %g)\n"
            "      --inertia KGM2     rotor + wheel inertia (default %g)\n"
            "      --damping NMS      viscous damping (default %g)\n"
            "      --vbus V           bridge supply (default %g)\n"
            "      --pole-pairs N     (default %d)\n"
            "      --elec-offset DEG  electrical angle at encoder zero (default 0)\n"
            "      --model-cycles N   CPU cycles per motor-model step (default %u)\n"
            "      --freq HZ          CPU clock (default 16000000)\n"
            "      --isr-stats        cycles per interrupt vector, printed as ISR lines at exit\n"
            "      --rx-mark HEX      print \"RXMARK t_us=T\" when the received frame HEX (its\n"
            "                         bytes before the 0x00, e.g. 040474a1) has reached UART0\n"
            "      --eeprom FILE      EEPROM contents from address 0 (at most 4096 bytes)\n"
            "      --no-bootloader    keep MCUSR on a reset (a board without the stk500v2 one)\n"
            "      --enc-noise COUNTS Gaussian noise of this rms on every angle read (default 0)\n"
            "      --cogging NM       cogging torque amplitude, 84 periods a turn (default 0)\n"
            "      --seed N           seed of the angle noise (default fixed)\n"
            "      --profile FILE     sample the PC inside the control step, write FILE at exit\n"
            "      --sim-pwm-timers   let simavr run Timers 1/3/4/5 (slow; needed only if the\n"
            "                         firmware uses their counters or interrupts)\n",
            prog, g_par.k_t_nm_per_v, g_par.k_e_vs_rad, g_par.j_kgm2, g_par.b_nms, g_par.vbus_v,
            g_par.pole_pairs, g_par.model_cycles);
}

enum {
    OPT_KT = 256,
    OPT_KE,
    OPT_J,
    OPT_B,
    OPT_VBUS,
    OPT_PP,
    OPT_OFFSET,
    OPT_MODEL,
    OPT_FREQ,
    OPT_SIMPWM,
    OPT_PROFILE,
    OPT_ISR,
    OPT_SPEED,
    OPT_UART_WAIT,
    OPT_RX_MARK,
    OPT_EEPROM,
    OPT_NO_BOOTLOADER,
    OPT_ENC_NOISE,
    OPT_COGGING,
    OPT_SEED
};

typedef struct {
    const char* elf;
    const char* pty_link;
    const char* eeprom;
    double run_s;
    uint32_t freq_hz;
} options_t;

static double parse_double(const char* s, const char* what) {
    char* end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !isfinite(v)) {
        fprintf(stderr, "fil_harness: bad value '%s' for %s\n", s, what);
        exit(2);
    }
    return v;
}

static void parse_enc_fault(const char* s) {
    int motor = -1;
    char mode[16] = "";
    if (sscanf(s, "%d:%15s", &motor, mode) != 2 || motor < 0 || motor >= N_MOTORS ||
        parse_fault(mode) < 0) {
        fprintf(stderr,
                "fil_harness: bad --enc-fault '%s' (want M:error|high|low|parity|frozen|weak)\n",
                s);
        exit(2);
    }
    g_mot[motor].fault = parse_fault(mode);
}

static void parse_options(int argc, char** argv, options_t* o) {
    static const struct option longopts[] = {
        {"time", required_argument, 0, 't'},
        {"free", no_argument, 0, 'f'},
        {"rate", required_argument, 0, 'r'},
        {"pty-link", required_argument, 0, 'l'},
        {"stats-period", required_argument, 0, 's'},
        {"enc-fault", required_argument, 0, 'e'},
        {"kt", required_argument, 0, OPT_KT},
        {"inertia", required_argument, 0, OPT_J},
        {"damping", required_argument, 0, OPT_B},
        {"vbus", required_argument, 0, OPT_VBUS},
        {"pole-pairs", required_argument, 0, OPT_PP},
        {"elec-offset", required_argument, 0, OPT_OFFSET},
        {"model-cycles", required_argument, 0, OPT_MODEL},
        {"freq", required_argument, 0, OPT_FREQ},
        {"sim-pwm-timers", no_argument, 0, OPT_SIMPWM},
        {"profile", required_argument, 0, OPT_PROFILE},
        {"isr-stats", no_argument, 0, OPT_ISR},
        {"ke", required_argument, 0, OPT_KE},
        {"speed-period", required_argument, 0, OPT_SPEED},
        {"uart-wait-max", required_argument, 0, OPT_UART_WAIT},
        {"rx-mark", required_argument, 0, OPT_RX_MARK},
        {"eeprom", required_argument, 0, OPT_EEPROM},
        {"no-bootloader", no_argument, 0, OPT_NO_BOOTLOADER},
        {"enc-noise", required_argument, 0, OPT_ENC_NOISE},
        {"cogging", required_argument, 0, OPT_COGGING},
        {"seed", required_argument, 0, OPT_SEED},
        {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    int c;
    while ((c = getopt_long(argc, argv, "t:fr:l:s:e:h", longopts, NULL)) != -1) {
        switch (c) {
            case 't':
                o->run_s = parse_double(optarg, "--time");
                break;
            case 'f':
                g_rate = 0;
                break;
            case 'r':
                g_rate = parse_double(optarg, "--rate");
                break;
            case 'l':
                o->pty_link = optarg;
                break;
            case 's':
                g_stats_period_s = parse_double(optarg, "--stats-period");
                break;
            case 'e':
                parse_enc_fault(optarg);
                break;
            case OPT_KT:
                g_par.k_t_nm_per_v = parse_double(optarg, "--kt");
                break;
            case OPT_J:
                g_par.j_kgm2 = parse_double(optarg, "--inertia");
                break;
            case OPT_B:
                g_par.b_nms = parse_double(optarg, "--damping");
                break;
            case OPT_VBUS:
                g_par.vbus_v = parse_double(optarg, "--vbus");
                break;
            case OPT_PP:
                g_par.pole_pairs = (int)parse_double(optarg, "--pole-pairs");
                break;
            case OPT_OFFSET:
                g_par.elec_offset_rad = parse_double(optarg, "--elec-offset") * TWO_PI / 360.0;
                break;
            case OPT_MODEL:
                g_par.model_cycles = (uint32_t)parse_double(optarg, "--model-cycles");
                break;
            case OPT_FREQ:
                o->freq_hz = (uint32_t)parse_double(optarg, "--freq");
                break;
            case OPT_ISR:
                g_isr_stats = 1;
                break;
            case OPT_PROFILE:
                g_profile_path = optarg;
                break;
            case OPT_SIMPWM:
                g_sim_pwm_timers = 1;
                break;
            case OPT_KE:
                g_par.k_e_vs_rad = parse_double(optarg, "--ke");
                break;
            case OPT_SPEED:
                g_speed_period_s = parse_double(optarg, "--speed-period");
                break;
            case OPT_RX_MARK:
                sim_rx_parse_mark(optarg);
                break;
            case OPT_EEPROM:
                o->eeprom = optarg;
                break;
            case OPT_NO_BOOTLOADER:
                g_keep_mcusr = 1;
                break;
            case OPT_ENC_NOISE:
                g_par.enc_noise_counts = parse_double(optarg, "--enc-noise");
                break;
            case OPT_COGGING:
                g_par.cogging_nm = parse_double(optarg, "--cogging");
                break;
            case OPT_SEED:
                g_rng = (uint64_t)parse_double(optarg, "--seed") * 2654435761ull + 1;
                break;
            case OPT_UART_WAIT:
                g_uart_wait_max_s = parse_double(optarg, "--uart-wait-max");
                break;
            default:
                usage(argv[0]);
                exit(c == 'h' ? 0 : 2);
        }
    }
    if (optind != argc - 1) {
        usage(argv[0]);
        exit(2);
    }
    o->elf = argv[optind];
    if (g_par.j_kgm2 <= 0 || g_par.model_cycles == 0 || g_par.pole_pairs <= 0) {
        fprintf(stderr, "fil_harness: --inertia, --model-cycles, --pole-pairs must be > 0\n");
        exit(2);
    }
    if (g_speed_period_s < 0 || g_stats_period_s < 0 || g_uart_wait_max_s < 0) {
        fprintf(stderr,
                "fil_harness: --speed-period, --stats-period, --uart-wait-max must be >= 0\n");
        exit(2);
    }
}

static void connect_peripherals(avr_t* avr, const char* pty_link) {
    /* UART0: no console echo, no usleep while the firmware polls an empty receiver */
    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)(AVR_UART_FLAG_POLL_SLEEP | AVR_UART_FLAG_STDIO);
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    uart_pty_init(avr, &g_pty);
    uart_pty_connect(&g_pty, '0');
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            uart_byte_out, NULL);
    if (pty_link) {
        unlink(pty_link);
        if (symlink(g_pty.pty.slavename, pty_link) != 0) {
            fprintf(stderr, "fil_harness: cannot link %s: %s\n", pty_link, strerror(errno));
            exit(1);
        }
    }
    printf("PTY %s\n", g_pty.pty.slavename); /* after the link: the line means "ready" */

    /* SPI bytes at the real SCK rate (sim_spi.h), answered by the four emulated encoders */
    if (sim_spi_install(avr, ADDR_SPDR, slaves_exchange) != 0) exit(1);
    sim_rx_install(avr, &g_pty, ADDR_UDR0);
    for (int i = 0; i < N_MOTORS; i++) {
        /* pin IRQs fire on changes only and start at 0: begin as "not selected" and let the
           firmware's first high write be a no-op, its first low write a frame start */
        g_mot[i].selected = 0;
        avr_irq_register_notify(
            avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('A'), IOPORT_IRQ_PIN4 + i),
            chip_select_changed, &g_mot[i]);
    }
    avr_register_io_write(avr, ADDR_GPIOR0, gpior0_write, NULL);
}

/* --eeprom: the file's bytes into the EEPROM from address 0. */
static int load_eeprom(avr_t* avr, const char* path) {
    static uint8_t buf[4096];
    FILE* f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "fil_harness: cannot read --eeprom %s\n", path);
        return -1;
    }
    size_t n = fread(buf, 1, sizeof(buf), f);
    fclose(f);
    avr_eeprom_desc_t d = {.ee = buf, .offset = 0, .size = (uint32_t)n};
    avr_ioctl(avr, AVR_IOCTL_EEPROM_SET, &d);
    return 0;
}

int main(int argc, char** argv) {
    options_t opt = {0};
    opt.freq_hz = 16000000;
    parse_options(argc, argv, &opt);
    setvbuf(stdout, NULL, _IOLBF, 0);

    elf_firmware_t fw;
    memset(&fw, 0, sizeof(fw));
    if (access(opt.elf, R_OK) != 0 || elf_read_firmware(opt.elf, &fw) != 0) {
        fprintf(stderr, "fil_harness: cannot read firmware ELF %s\n", opt.elf);
        return 1;
    }
    g_avr = avr_make_mcu_by_name("atmega2560");
    if (!g_avr) {
        fprintf(stderr, "fil_harness: simavr has no atmega2560\n");
        return 1;
    }
    avr_init(g_avr);
    strcpy(fw.mmcu, "atmega2560");
    fw.frequency = opt.freq_hz;
    avr_load_firmware(g_avr, &fw);
    g_avr->frequency = opt.freq_hz;
    g_avr->sleep = no_sleep;
    if (opt.eeprom && load_eeprom(g_avr, opt.eeprom) != 0) return 2;
    g_tick_cycles = opt.freq_hz / 1000;

    connect_peripherals(g_avr, opt.pty_link);
    if (!g_sim_pwm_timers) detach_pwm_timers(g_avr);
    /* INT0..7 default to "low level" sense; simavr 1.6 then polls every low pin every few cycles
       through avr_ioctl() (avr_extint_poll_level_trig), enabled or not. PE4/PE5 (INT4/5) are
       the OC3B/OC3C outputs, so that polling alone halved the simulation speed. The wheel
       firmware uses no external interrupt; level sense then acts like an edge. */
    for (uint8_t i = 0; i < EXTINT_COUNT; i++) avr_extint_set_strict_lvl_trig(g_avr, i, 0);
    if (g_profile_path) g_profile = calloc(0x20000, sizeof(uint32_t));
    register_timers(g_avr);
    avr_register_io(g_avr, &g_reset_io);

    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    signal(SIGUSR1, on_usr1);
    pthread_t cmd_thread;
    pthread_create(&cmd_thread, NULL, stdin_thread, NULL);
    pthread_detach(cmd_thread);

    avr_cycle_count_t end_cycle =
        opt.run_s > 0 ? (avr_cycle_count_t)(opt.run_s * opt.freq_hz) : (avr_cycle_count_t)-1;
    g_wall_t0 = now_s();
    int state = cpu_Running;
    while (!g_stop && g_avr->cycle < end_cycle) {
        state = avr_run(g_avr);
        if (state == cpu_Done || state == cpu_Crashed) break;
        if (g_isr_stats) isr_track();
        if (sim_rx_inject_pending) sim_rx_inject_start();
        if (g_tick_stop_request) {
            g_tick_stop_request = 0;
            stop_tick_timer();
        }
        if (g_brown_out_request) { /* the supply dipped below the BOD level: reset, BORF set */
            g_brown_out_request = 0;
            printf("OK brown-out t_s=%.6f\n", sim_time_s());
            fflush(stdout);
            avr_reset(g_avr);
            g_avr->data[ADDR_MCUSR] = 0x04;
        }
        if (g_hang_request) {
            hang_cpu(g_hang_request == 2);
            g_hang_request = 0;
        }
        if (g_pwm_request) {
            g_pwm_request = 0;
            print_pwm();
        }
        if (g_stats_request) {
            g_stats_request = 0;
            print_stats("OK stats", &g_cyc_total); /* whole run so far */
        }
    }
    if (state == cpu_Crashed) printf("CRASHED pc=0x%05x\n", (unsigned)g_avr->pc);
    print_stats("FINAL", &g_cyc_total);
    if (g_isr_stats) print_isr_stats();
    write_profile();
    /* no uart_pty_stop(): it hangs in pthread_join (simavr 1.6); exit ends its thread */
    if (opt.pty_link) unlink(opt.pty_link);
    fflush(stdout);
    _exit(state == cpu_Crashed ? 3 : 0);
}
