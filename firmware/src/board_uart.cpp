// board_uart.cpp - UART0 at 1000000 baud with interrupt-driven RX and TX rings.
// Single producer / single consumer per ring with 8-bit indices: each index is written by one
// side only and 8-bit loads/stores are atomic on AVR, so no interrupt locking is needed.
#include <avr/interrupt.h>

#include "board.h"
#include "board_io.h"
#include "proto.h"

static_assert(BOARD_UART_RX_SIZE == 256, "RX ring uses free-running 8-bit indices");
static_assert(BOARD_UART_TX_SIZE == 256, "TX ring uses free-running 8-bit indices");

static volatile uint8_t rx_buf[BOARD_UART_RX_SIZE];
static volatile uint8_t rx_head;  // written by the ISR
static volatile uint8_t rx_tail;  // written by the main loop
static volatile uint8_t rx_overflow;
static volatile uint8_t tx_buf[BOARD_UART_TX_SIZE];
static volatile uint8_t tx_head;  // written by the main loop
static volatile uint8_t tx_tail;  // written by the ISR

// STOP_ALL as a real-time command (as grbl's feed hold): the receive interrupt compares the bytes
// since the last delimiter with the STOP_ALL wire frame, so a stop does not wait behind the
// frames queued in the ring. stop_match: bytes of the frame matched so far (0..4), or
// PROTO_STOP_ALL_WIRE_LEN when this frame is something else (until the next 0x00).
static const uint8_t k_stop_wire[PROTO_STOP_ALL_WIRE_LEN] = PROTO_STOP_ALL_WIRE;
static volatile uint8_t stop_match;
static volatile uint8_t stop_request;

void uart_init() {
    UBRR0 = BOARD_UART_UBRR;
    UCSR0A = _BV(U2X0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);  // 8N1
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

// USART0_RX, per received byte: the ring store and the STOP_ALL match. Budget: at 1 Mbaud a byte
// arrives every 160 cycles, and this ISR must leave the main loop most of them; measured cost in
// docs/hardware.md, "ISR costs" (make -C firmware cycles).
ISR(USART0_RX_vect) {
    const uint8_t b = UDR0;
    const uint8_t h = rx_head;
    const uint8_t next = static_cast<uint8_t>(h + 1);
    if (next == rx_tail) {
        rx_overflow = 1;  // byte lost; counted by the main loop
    } else {
        rx_buf[h] = b;
        rx_head = next;
    }
    uint8_t m = stop_match;
    if (b == 0) {
        if (m == PROTO_STOP_ALL_WIRE_LEN - 1) stop_request = 1;
        m = 0;
    } else if (m < PROTO_STOP_ALL_WIRE_LEN - 1 && b == k_stop_wire[m]) {
        m++;
    } else {
        m = PROTO_STOP_ALL_WIRE_LEN;
    }
    stop_match = m;
}

// USART0_UDRE: 55..60 cycles first instruction to reti + 8 entry = 63..68 per sent byte (simavr).
ISR(USART0_UDRE_vect) {
    uint8_t t = tx_tail;
    if (t == tx_head) {
        UCSR0B &= static_cast<uint8_t>(~_BV(UDRIE0));  // ring empty: stop the interrupt
        return;
    }
    UDR0 = tx_buf[t];
    tx_tail = static_cast<uint8_t>(t + 1);
}

bool uart_tx_frame(const uint8_t* data, uint8_t len) {
    uint8_t h = tx_head;
    uint8_t used = static_cast<uint8_t>(h - tx_tail);
    if (static_cast<uint16_t>(used) + len > BOARD_UART_TX_SIZE - 1) return false;
    for (uint8_t i = 0; i < len; i++) tx_buf[static_cast<uint8_t>(h + i)] = data[i];
    tx_head = static_cast<uint8_t>(h + len);
    // Read-modify-write of a memory-mapped register: the UDRE ISR may clear UDRIE0 in between,
    // which is harmless because this write sets it again and the ring is not empty.
    UCSR0B |= _BV(UDRIE0);
    return true;
}

bool uart_rx_pop(uint8_t* byte) {
    uint8_t t = rx_tail;
    if (t == rx_head) return false;
    *byte = rx_buf[t];
    rx_tail = static_cast<uint8_t>(t + 1);
    return true;
}

bool uart_rx_take_overflow() {
    if (!rx_overflow) return false;
    rx_overflow = 0;
    return true;
}

bool uart_take_stop_request() {
    if (!stop_request) return false;
    stop_request = 0;
    return true;
}
