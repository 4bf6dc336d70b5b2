// main.cpp - wheel board firmware: initialisation and the main loop around the portable app.
#include <avr/interrupt.h>
#include <avr/wdt.h>

#include "app.h"
#include "app_step.h"
#include "board.h"
#include "board_enc_io.h"
#include "board_io.h"

// Maximum received bytes handled per loop pass, so that a burst cannot delay the tick much: at
// 1 Mbaud with 32 a connect's burst of requests delayed a step by up to 920 us (step_max_us).
// main_handle_rx also stops at a pending tick, so at most one frame's dispatch (its reply
// built) lies between a tick and its step.
#define MAIN_RX_BYTES_PER_PASS 8

static app_state g_app;
static uint8_t g_reset_cause __attribute__((section(".noinit")));

// Runs before main (.init3): keep the reset cause and stop a watchdog left running by a
// watchdog reset (it would otherwise fire again during start-up).
extern "C" void main_early_init() __attribute__((naked, used, section(".init3")));
extern "C" void main_early_init() {
    g_reset_cause = MCUSR;
    MCUSR = 0;
    wdt_disable();
}

// tick_seen: the tick count the main loop last handled. The encoders are sampled when the step
// starts, so its delay after the tick moves the sample instant: the speed estimate sees a longer
// (then shorter) interval, a transient of about 1 % per 80 us of delay after its filter.
static void main_handle_rx(uint8_t tick_seen) {
    uint8_t b;
    for (uint8_t i = 0; i < MAIN_RX_BYTES_PER_PASS && g_tick_count == tick_seen && uart_rx_pop(&b);
         i++) {
        app_rx_byte(&g_app, b);
    }
    if (uart_rx_take_overflow()) app_note_rx_overflow(&g_app);
}

int main() {
    pwm_init();
    spi_init();
    uart_init();
    uint16_t boot_faults =
        (g_reset_cause & _BV(WDRF)) ? static_cast<uint16_t>(PROTO_FAULT_WATCHDOG_RESET) : 0u;
    app_init(&g_app, &g_board_eeprom, uart_tx_frame, boot_faults);
    tick_init();
    wdt_enable(WDTO_30MS);
    sei();

    uint8_t last_tick = g_tick_count;
    uint32_t t_ms = 0;
    for (;;) {
        wdt_reset();
        main_handle_rx(last_tick);
        app_poll(&g_app);
        uint8_t now = g_tick_count;
        uint8_t elapsed = static_cast<uint8_t>(now - last_tick);
        if (elapsed == 0) continue;
        if (elapsed > 1) app_note_overrun(&g_app, static_cast<uint8_t>(elapsed - 1));
        BOARD_TICK_MARK = 1;
        last_tick = now;
        t_ms += elapsed;

        board_enc_io io;
        // Measured step (make -C firmware cycles: 4 wheels closed loop at 715 rpm, encoder reads
        // included, 1,993 steps): 1336 / 2290 / 2336 cycles min / mean / max without the ISRs
        // that preempt it (14.3 % / 14.6 % of the 16,000-cycle tick; target 2400), 2917 max with
        // them (a host frame's RX bytes); docs/hardware.md, "Control-step cycles", has how each
        // change to the step moved these figures.
        BOARD_CYCLE_MARK = 1;
        app_control_step_io(&g_app, io);
        BOARD_CYCLE_MARK = 0;
        pwm_apply(g_app.pwm, g_app.enable_mask);
        if (g_app.enc_clear) enc_clear_errors(g_app.enc_clear);  // rare: after a bad word
        app_setpoints_tick(&g_app);  // heartbeat, fail-safe, ramp: used by the next step
        app_note_step_time(&g_app, static_cast<uint16_t>(TCNT2 * BOARD_TICK_US_PER_COUNT));
        // Supervision and one encoder's diagnostics register, outside step_max_us.
        app_supervise(&g_app);
        const uint8_t diag = app_diag_wheel(&g_app);  // one encoder per tick, round robin
        if (diag < BOARD_WHEELS) app_diag_result(&g_app, diag, enc_read_diag(diag));
        BOARD_TELEM_MARK = 1;
        app_telemetry(&g_app, t_ms * 1000u);
        BOARD_TELEM_MARK = 0;
        BOARD_TICK_MARK = 0;
    }
}
