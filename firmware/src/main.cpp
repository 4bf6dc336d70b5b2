// main.cpp - wheel board firmware: initialisation and the main loop around the portable app.
#include <avr/interrupt.h>
#include <avr/wdt.h>

#include "app.h"
#include "app_step.h"
#include "board.h"
#include "board_enc_io.h"
#include "board_io.h"

// The main loop runs one bounded job at a time and, before each, the control step if a tick is
// pending: a step waits for at most the rest of one job, whatever the link brings. The jobs: the
// tick's own work after the step (supervision, one encoder's diagnostics read, a telemetry frame
// in slices: app.h), a reply's CRC and then its COBS and queueing, a received frame's CRC and
// checks and then its dispatch (app_rx_act), the decoding of up to MAIN_RX_BYTES_PER_PASS
// received bytes (at most one frame's COBS, at its delimiter), and the move of the receive
// interrupt's ring into g_rx_fifo (about 12 cycles a byte, stopped at a pending tick). Each job is
// a pass of the loop, so what a pass tests when it finds nothing to do is inline.
// docs/hardware.md ("Link load") has the longest job and the bound it gives the step.
#define MAIN_RX_BYTES_PER_PASS 8
// Received bytes wait here between the interrupt's 256-byte ring and the decoder. A burst at the
// line rate comes in faster than its frames are dispatched (a PARAM_SET takes about 3,000 cycles
// in its jobs, the time of 19 received bytes); together the two hold 768 bytes, three of the
// documented bursts.
#define MAIN_RX_FIFO_SIZE 512u  // power of two

static app_state g_app;
static uint8_t g_rx_fifo[MAIN_RX_FIFO_SIZE];
static uint16_t g_rx_in;   // bytes put into g_rx_fifo, free-running
static uint16_t g_rx_out;  // bytes taken from it
// The reset cause (PROTO_FAULT_* bits), found in main_early_init (.noinit: set before .bss).
static uint16_t g_boot_faults __attribute__((section(".noinit")));

// Runs before main and before .data and .bss are set up (.init3): every output off first, then
// the reset cause, then a watchdog left running by a watchdog reset stopped (it would fire again
// during start-up). The cause: the tick interrupt's hang mark, or MCUSR where no bootloader
// cleared it (WDRF; BORF without PORF: a brown-out, the supply below the BOD level).
extern "C" void main_early_init() __attribute__((naked, used, section(".init3")));
extern "C" void main_early_init() {
    board_outputs_off();
    const uint8_t mcusr = MCUSR;
    uint16_t cause = 0;
    if (g_wdt_mark == BOARD_WDT_MARK || (mcusr & _BV(WDRF))) cause = PROTO_FAULT_WATCHDOG_RESET;
    if ((mcusr & (_BV(BORF) | _BV(PORF))) == _BV(BORF)) cause |= PROTO_FAULT_BROWN_OUT_RESET;
    g_boot_faults = cause;
    g_wdt_mark = 0;
    MCUSR = 0;
    wdt_disable();
}

// Watchdog in plain system-reset mode, 16 ms (board.h); interrupts are still off here.
static void main_watchdog_start() {
    wdt_enable(WDTO_15MS);
}

// The tick's work after its step, one job each (main_after_work): the parameters a PARAM_SET
// left stale derived, the supervision of wheels 0..3, one encoder's diagnostics register; then
// the telemetry frame's slices.
enum : uint8_t {
    MAIN_AFTER_NONE,
    MAIN_AFTER_CTL,
    MAIN_AFTER_SUPERVISE,  // + wheel
    MAIN_AFTER_DIAG = MAIN_AFTER_SUPERVISE + BOARD_WHEELS
};
static uint8_t g_after;

// tick_seen: the tick count the main loop last handled. The encoders are sampled when the step
// starts, so its delay after the tick moves the sample instant: the speed estimate sees a longer
// (then shorter) interval, a transient of about 1 % per 80 us of delay after its filter.
static void main_move_rx(uint8_t tick_seen) {
    uint8_t b;
    while (g_tick_count == tick_seen &&
           static_cast<uint16_t>(g_rx_in - g_rx_out) < MAIN_RX_FIFO_SIZE && uart_rx_peek(&b)) {
        uart_rx_next();
        g_rx_fifo[g_rx_in++ & (MAIN_RX_FIFO_SIZE - 1)] = b;
    }
    if (uart_rx_take_overflow()) app_note_rx_overflow(&g_app, uart_stops_seen());
}

// Up to MAIN_RX_BYTES_PER_PASS bytes into the decoder; it stops at a frame that waits for
// app_rx_act, so one call decodes at most one frame.
static void main_decode_rx(uint8_t tick_seen) {
    for (uint8_t i = 0;
         i < MAIN_RX_BYTES_PER_PASS && g_tick_count == tick_seen && g_rx_out != g_rx_in; i++) {
        if (app_rx_decode(&g_app, g_rx_fifo[g_rx_out++ & (MAIN_RX_FIFO_SIZE - 1)])) return;
    }
}

// The step job: the control step and the PWM (step_max_us ends here), then what the next step
// needs (a STOP_ALL seen, the heartbeat, the ramp) and the telemetry's values of this step.
static void main_tick(uint8_t elapsed, uint32_t t_ms) {
    if (elapsed > 1) app_note_overrun(&g_app, static_cast<uint8_t>(elapsed - 1));
    BOARD_TICK_MARK = 1;
    board_enc_io io;
    // Measured step (make -C firmware cycles: 4 wheels closed loop at 715 rpm, encoder reads
    // included): docs/hardware.md, "Control-step cycles", has the figures;
    // reports/firmware-timing.md how each change to the step moved them.
    BOARD_CYCLE_MARK = 1;
    app_control_step_io(&g_app, io);
    BOARD_CYCLE_MARK = 0;
    pwm_apply(g_app.pwm, g_app.enable_mask);
    uart_tx_release();
    // step_max_us: from the tick to the outputs updated, preempting ISRs included
    app_note_step_time(&g_app, static_cast<uint16_t>(TCNT2 * BOARD_TICK_US_PER_COUNT));
    wdt_reset();  // only here: a step that no longer runs (Timer2 stopped, a hang) trips it
    g_ticks_since_step = 0;
    if (g_app.enc_clear) enc_clear_errors(g_app.enc_clear);  // rare: after a bad word
    // A STOP_ALL the receive interrupt saw since the last tick: taken right before the ramp,
    // so that the next step brakes. Its last byte to the step that brakes: under 2 ms.
    app_note_stops_seen(&g_app, uart_stops_seen());
    app_setpoints_tick(&g_app);  // heartbeat, fail-safe, ramp: used by the next step
    app_telemetry_begin(&g_app, t_ms * 1000u);
    // The jobs of the last step that the CPU left no time for before this tick (a link flood on
    // top of the tick's work) are not run: the supervision is of this step.
    g_after = MAIN_AFTER_CTL;
}

// One job of the tick's work after its step (a half of the parameters' derivation, a wheel's
// supervision or the diagnostics read; docs/hardware.md has their cycles), then the telemetry
// frame's slices. False when none is left.
static bool main_after_work() {
    const uint8_t job = g_after;
    if (job != MAIN_AFTER_NONE) {
        if (job == MAIN_AFTER_CTL) {
            if (app_derive_ctl(&g_app)) return true;  // the second half in the next job
        } else if (job < MAIN_AFTER_DIAG) {
            app_supervise(&g_app, static_cast<uint8_t>(job - MAIN_AFTER_SUPERVISE));
        } else {
            const uint8_t diag = app_diag_wheel(&g_app);  // one encoder per tick, round robin
            if (diag < BOARD_WHEELS) app_diag_result(&g_app, diag, enc_read_diag(diag));
        }
        g_after = static_cast<uint8_t>(job == MAIN_AFTER_DIAG ? MAIN_AFTER_NONE : job + 1);
        return true;
    }
    BOARD_TELEM_MARK = 1;
    const bool sliced = app_telemetry_work(&g_app);
    BOARD_TELEM_MARK = 0;
    if (!sliced) BOARD_TICK_MARK = 0;
    return sliced;
}

int main() {
    pwm_init();
    spi_init();
    app_init(&g_app, &g_board_eeprom, uart_tx_frame, g_boot_faults);
    tick_init();
    main_watchdog_start();
    // The receiver last: enabled earlier, bytes arriving during app_init (interrupts still off)
    // would overrun the UART's 2-byte receive buffer.
    uart_init();
    sei();

    uint8_t last_tick = g_tick_count;
    uint32_t t_ms = 0;
    for (;;) {
        const uint8_t now = g_tick_count;
        if (now != last_tick) {
            const uint8_t elapsed = static_cast<uint8_t>(now - last_tick);
            last_tick = now;
            t_ms += elapsed;
            main_tick(elapsed, t_ms);
            continue;
        }
        main_move_rx(last_tick);
        if (main_after_work()) continue;
        if (app_reply_work(&g_app)) continue;
        if (app_rx_waits(&g_app)) {
            app_rx_act(&g_app);
            continue;
        }
        main_decode_rx(last_tick);
        app_poll(&g_app);
    }
}
