/* uart.c - see uart.h.
 *
 * At 1 Mbaud a byte arrives every 10 us (160 cycles), so reception is an ISR into a ring
 * and the main loop decodes frames at leisure; transmission drains a ring from the UDRE
 * interrupt. Ring indices are uint8_t and only one side writes each index, so no locking. */
#include "uart.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "protocol_frames.h"

#define RX_SIZE 128u /* power of two: 12.8 ms of a full-speed line */
#define TX_SIZE 256u /* uint8_t indices wrap by themselves: 5 telemetry frames */

static volatile uint8_t rx_buf[RX_SIZE];
static volatile uint8_t rx_head, rx_tail;
static volatile uint8_t tx_buf[TX_SIZE];
static volatile uint8_t tx_head, tx_tail;
static volatile uint16_t rx_overruns;

void uart_init(void)
{
    /* U2X before UBRR: the hardware does not care, but simavr derives the bit time when UBRR is
     * written, and would otherwise run this UART at half speed in the firmware-in-the-loop. */
    UCSR0A = _BV(U2X0);
    UBRR0 = PROTO_UBRR;
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

ISR(USART0_RX_vect)
{
    uint8_t status = UCSR0A;
    uint8_t byte = UDR0;
    if (status & _BV(DOR0))
        rx_overruns++;
    uint8_t next = (rx_head + 1u) & (RX_SIZE - 1u);
    if (next == rx_tail) {
        rx_overruns++;
        return;
    }
    rx_buf[rx_head] = byte;
    rx_head = next;
}

ISR(USART0_UDRE_vect)
{
    if (tx_tail == tx_head) {
        UCSR0B &= (uint8_t)~_BV(UDRIE0);
        return;
    }
    UDR0 = tx_buf[tx_tail];
    tx_tail++;
}

int16_t uart_getc(void)
{
    if (rx_tail == rx_head)
        return -1;
    uint8_t byte = rx_buf[rx_tail];
    rx_tail = (rx_tail + 1u) & (RX_SIZE - 1u);
    return byte;
}

uint8_t uart_rx_pending(void)
{
    return rx_tail != rx_head;
}

uint8_t uart_write(const uint8_t *data, uint8_t n)
{
    uint8_t free_bytes = (uint8_t)(tx_tail - tx_head - 1u); /* one slot stays empty */
    if (n > free_bytes)
        return 0;
    uint8_t head = tx_head;
    for (uint8_t i = 0; i < n; i++)
        tx_buf[head++] = data[i];
    tx_head = head;
    UCSR0B |= _BV(UDRIE0);
    return 1;
}

uint16_t uart_rx_overruns(void)
{
    uint16_t n;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { n = rx_overruns; }
    return n;
}
