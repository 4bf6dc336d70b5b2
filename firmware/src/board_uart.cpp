// board_uart.cpp - UART0 at 1000000 baud with interrupt-driven RX and TX rings.
// Single producer / single consumer per ring with 8-bit indices: each index is written by one
// side only and 8-bit loads/stores are atomic on AVR, so no interrupt locking is needed.
#include <avr/interrupt.h>

#include "board.h"
#include "board_io.h"
#include "proto.h"

static_assert(BOARD_UART_RX_SIZE == 256, "RX ring: free-running 8-bit indices, aligned");
static_assert(BOARD_UART_TX_SIZE == 256, "TX ring: free-running 8-bit indices, aligned");

// The rings are aligned to 256 bytes so that an index is the low byte of the address: the
// interrupts then form the pointer with one LDI. extern "C": the assembly names them. In the
// plain .data section, which the linker puts first in RAM, at 0x200: aligned there, they need no
// padding, where after the other variables up to 255 bytes of RAM would go to it. The price is
// their 512 zero bytes in flash, copied at boot.
#define BOARD_UART_RING __attribute__((section(".data"), aligned(256)))
extern "C" {
volatile uint8_t board_rx_buf[BOARD_UART_RX_SIZE] BOARD_UART_RING;
volatile uint8_t board_tx_buf[BOARD_UART_TX_SIZE] BOARD_UART_RING;
volatile uint8_t board_rx_head;  // written by the RX ISR
volatile uint8_t board_rx_tail;  // written by the main loop
volatile uint8_t board_rx_overflow;
volatile uint8_t board_tx_head;  // written by the main loop
volatile uint8_t board_tx_tail;  // written by the UDRE ISR
volatile uint8_t board_tx_held;  // set by the tick ISR, cleared by uart_tx_release
// STOP_ALL as a real-time command (as grbl's feed hold): the receive interrupt compares the bytes
// since the last delimiter with the STOP_ALL wire frame, so a stop does not wait behind the
// frames queued in the ring. board_stop_match: bytes of the frame matched so far (0..4), 5 when
// this frame is something else (until the next 0x00).
volatile uint8_t board_stop_match;
volatile uint8_t board_stops_seen;
}

static constexpr uint8_t k_stop_wire[PROTO_STOP_ALL_WIRE_LEN] = PROTO_STOP_ALL_WIRE;
static_assert(PROTO_STOP_ALL_WIRE_LEN == 5 && k_stop_wire[4] == 0, "4 bytes and the delimiter");

void uart_init() {
    UBRR0 = BOARD_UART_UBRR;
    UCSR0A = _BV(U2X0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);  // 8N1
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

// USART0_RX, once per received byte, at most every 160 cycles at 1 Mbaud: the ring store and the
// STOP_ALL match in assembly. Budget, measured (make -C firmware cycles): 49 cycles from the first
// instruction to reti on the common path (a byte of any frame but STOP_ALL: prologue 11, ring 17,
// match 6, epilogue 15), 57 with the 8 of response and vector jump, up to 64 + 8 while a STOP_ALL
// matches and 3 more on its delimiter (the count; gcc's C for the same work took 83-92). With the
// 40 of the UDRE interrupt, a full-duplex burst (a byte each way every 160 cycles) leaves the main
// loop 39 % of the CPU (docs/hardware.md, "ISR costs").
ISR(USART0_RX_vect, ISR_NAKED) {
    __asm__ __volatile__(
        "push r30\n\t"
        "in r30, __SREG__\n\t"
        "push r30\n\t"
        "push r31\n\t"
        "push r24\n\t"
        "push r25\n\t"
        "lds r24, %[udr]\n\t"  // b
        "lds r30, board_rx_head\n\t"
        "mov r25, r30\n\t"
        "inc r25\n\t"  // next head
        "lds r31, board_rx_tail\n\t"
        "cp r25, r31\n\t"
        "breq 1f\n\t"
        "sts board_rx_head, r25\n\t"
        "ldi r31, hi8(board_rx_buf)\n\t"
        "st Z, r24\n"
        "2:\n\t"
        "lds r25, board_stop_match\n\t"
        "tst r24\n\t"
        "breq 5f\n\t"
        "cpi r25, 5\n\t"
        "breq 9f\n\t"  // a byte of another frame: the common path
        "cpi r25, 4\n\t"
        "brsh 4f\n\t"  // 4 matched and another byte, or already another frame
        "cpi r25, 1\n\t"
        "brlo 10f\n\t"
        "breq 11f\n\t"
        "cpi r25, 3\n\t"
        "brlo 12f\n\t"
        "cpi r24, %[k3]\n\t"
        "rjmp 3f\n"
        "10:\n\t"
        "cpi r24, %[k0]\n\t"
        "rjmp 3f\n"
        "11:\n\t"
        "cpi r24, %[k1]\n\t"
        "rjmp 3f\n"
        "12:\n\t"
        "cpi r24, %[k2]\n"
        "3:\n\t"
        "brne 4f\n\t"
        "inc r25\n\t"
        "sts board_stop_match, r25\n\t"
        "rjmp 9f\n"
        "4:\n\t"
        "ldi r25, 5\n\t"
        "sts board_stop_match, r25\n\t"
        "rjmp 9f\n"
        "5:\n\t"  // delimiter: a STOP_ALL if exactly its 4 bytes came since the last one
        "cpi r25, 4\n\t"
        "brne 6f\n\t"
        "lds r25, board_stops_seen\n\t"  // +5 cycles, on a STOP_ALL's delimiter only
        "inc r25\n\t"
        "sts board_stops_seen, r25\n"
        "6:\n\t"
        "sts board_stop_match, r24\n"  // r24 = 0
        "9:\n\t"
        "pop r25\n\t"
        "pop r24\n\t"
        "pop r31\n\t"
        "pop r30\n\t"
        "out __SREG__, r30\n\t"
        "pop r30\n\t"
        "reti\n"
        "1:\n\t"  // ring full: the byte is lost, counted by the main loop
        "ldi r25, 1\n\t"
        "sts board_rx_overflow, r25\n\t"
        "rjmp 2b\n\t" ::[udr] "n"(_SFR_MEM_ADDR(UDR0)),
        [k0] "n"(k_stop_wire[0]), [k1] "n"(k_stop_wire[1]), [k2] "n"(k_stop_wire[2]),
        [k3] "n"(k_stop_wire[3]));
}

// USART0_UDRE, once per sent byte: 31-34 cycles to reti, 39-42 with the 8 of entry (gcc's C
// took 63-68).
ISR(USART0_UDRE_vect, ISR_NAKED) {
    __asm__ __volatile__(
        "push r30\n\t"
        "in r30, __SREG__\n\t"
        "push r30\n\t"
        "push r31\n\t"
        "lds r30, board_tx_tail\n\t"
        "lds r31, board_tx_head\n\t"
        "cp r30, r31\n\t"
        "breq 1f\n\t"
        "ldi r31, hi8(board_tx_buf)\n\t"
        "ld r31, Z+\n\t"  // ZL = tail + 1 (wraps at 256: the ring is aligned)
        "sts %[udr], r31\n\t"
        "sts board_tx_tail, r30\n\t"
        "rjmp 2f\n"
        "1:\n\t"  // ring empty: stop the interrupt
        "lds r31, %[ucsrb]\n\t"
        "andi r31, %[noudrie]\n\t"
        "sts %[ucsrb], r31\n"
        "2:\n\t"
        "pop r31\n\t"
        "pop r30\n\t"
        "out __SREG__, r30\n\t"
        "pop r30\n\t"
        "reti\n\t" ::[udr] "n"(_SFR_MEM_ADDR(UDR0)),
        [ucsrb] "n"(_SFR_MEM_ADDR(UCSR0B)), [noudrie] "n"(static_cast<uint8_t>(~_BV(UDRIE0))));
}

bool uart_tx_frame(const uint8_t* data, uint8_t len) {
    uint8_t h = board_tx_head;
    uint8_t used = static_cast<uint8_t>(h - board_tx_tail);
    if (static_cast<uint16_t>(used) + len > BOARD_UART_TX_SIZE - 1) return false;
    for (uint8_t i = 0; i < len; i++) board_tx_buf[static_cast<uint8_t>(h + i)] = data[i];
    board_tx_head = static_cast<uint8_t>(h + len);
    // Read-modify-write of a memory-mapped register: the UDRE ISR may clear UDRIE0 in between,
    // which is harmless because this write sets it again and the ring is not empty. Interrupts
    // off so that a tick between the test and the write cannot leave the TX interrupt on.
    const uint8_t sreg = SREG;
    cli();
    if (!board_tx_held) UCSR0B |= _BV(UDRIE0);
    SREG = sreg;
    return true;
}

uint8_t uart_stops_seen() {
    return board_stops_seen;
}  // one byte: read atomically
