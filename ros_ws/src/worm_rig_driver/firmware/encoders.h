/* encoders.h - three quadrature encoders decoded 4x in the external interrupts INT0..INT5.
 * Positive counts when channel A leads B (positive rotation). Counts wrap as int32. */
#ifndef ENCODERS_H
#define ENCODERS_H

#include <stdint.h>

#include "board.h"

void encoders_init(void);
/* The counts now, extended to 32 bits: call from the tick ISR only, once per tick (at least
 * every 32767 counts of the fastest encoder); the encoder ISRs may preempt it. */
void encoders_snapshot_isr(int32_t counts[MOTOR_COUNT]);
/* Invalid transitions (both channels changed between two interrupts) since reset (wraps). */
uint16_t encoders_errors(void);

#endif /* ENCODERS_H */
