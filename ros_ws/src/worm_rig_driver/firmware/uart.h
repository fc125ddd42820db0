/* uart.h - USART0 at PROTO_BAUD (1 Mbaud: U2X, UBRR 1, exact at 16 MHz), interrupt-driven rings. */
#ifndef UART_H
#define UART_H

#include <stdint.h>

void uart_init(void);
/* Next received byte, or -1 if none. */
int16_t uart_getc(void);
/* 1 if a byte is waiting (for the sleep decision). */
uint8_t uart_rx_pending(void);
/* Queue n bytes for sending, all or nothing: returns 0 (nothing queued) if the ring lacks room. */
uint8_t uart_write(const uint8_t *data, uint8_t n);
/* Bytes lost on reception: receive ring full or hardware overrun (wraps). */
uint16_t uart_rx_overruns(void);

#endif /* UART_H */
