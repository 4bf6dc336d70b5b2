// board_pwm.cpp - 12 PWM channels on Timers 1/3/4/5 and the four driver enables.
#include "board.h"
#include "board_io.h"
#include "commut.h"

static_assert(BOARD_PWM_TOP == CMT_PWM_TOP, "commutation and timer TOP differ");
static_assert(BOARD_PWM_TOP + 1 == (BOARD_PWM0_TOP + 1) << BOARD_PWM0_SHIFT,
              "Timer0 and the 16-bit timers run at different PWM frequencies");

void pwm_init() {
    // Timers 0, 1, 3, 4, 5 share one prescaler: held in reset (TSM) while they are set up, then
    // released at once, so Timer0 (clk/8, TOP 99) and the 16-bit timers (clk/1, TOP 799) count
    // from 0 together and their 20 kHz periods stay aligned.
    GTCCR = _BV(TSM) | _BV(PSRSYNC);
    ICR1 = BOARD_PWM_TOP;
    ICR3 = BOARD_PWM_TOP;
    ICR4 = BOARD_PWM_TOP;
    ICR5 = BOARD_PWM_TOP;
    OCR0A = BOARD_PWM0_TOP;
    OCR1A = OCR1B = 0;
    OCR0B = 0;
    OCR3A = OCR3B = OCR3C = 0;
    OCR4A = OCR4B = OCR4C = 0;
    OCR5A = OCR5B = OCR5C = 0;
    TCNT0 = 0;
    TCNT1 = TCNT3 = TCNT4 = TCNT5 = 0;
    TCCR1A = BOARD_PWM_TCCRA(1) & ~_BV(COM1C1);  // OC1C (PB7, the LED) stays a port pin
    TCCR3A = BOARD_PWM_TCCRA(3);
    TCCR4A = BOARD_PWM_TCCRA(4);
    TCCR5A = BOARD_PWM_TCCRA(5);
    TCCR0A = BOARD_PWM0_TCCRA;
    TCCR1B = BOARD_PWM_TCCRB(1);
    TCCR3B = BOARD_PWM_TCCRB(3);
    TCCR4B = BOARD_PWM_TCCRB(4);
    TCCR5B = BOARD_PWM_TCCRB(5);
    TCCR0B = BOARD_PWM0_TCCRB;
    GTCCR = 0;
}

void pwm_apply(const uint16_t duty[][3], uint8_t enable_mask) {
    // OCRnx are double-buffered in modes 14 and 7 (taken over at TOP/BOTTOM): no glitch
    // mid-period.
    // No ISR touches a 16-bit timer register, so the shared TEMP byte needs no locking.
    OCR1A = duty[0][0];
    OCR1B = duty[0][1];
    OCR0B = static_cast<uint8_t>(duty[0][2] >> BOARD_PWM0_SHIFT);
    OCR3A = duty[1][0];
    OCR3B = duty[1][1];
    OCR3C = duty[1][2];
    OCR4A = duty[2][0];
    OCR4B = duty[2][1];
    OCR4C = duty[2][2];
    OCR5A = duty[3][0];
    OCR5B = duty[3][1];
    OCR5C = duty[3][2];
    uint8_t en = static_cast<uint8_t>((enable_mask << BOARD_EN_SHIFT) & BOARD_EN_MASK);
    BOARD_EN_PORT = static_cast<uint8_t>((BOARD_EN_PORT & ~BOARD_EN_MASK) | en);
}
