/* adc_mux.h - the six analogue channels through two SN74HC4051 multiplexers.
 *
 * Mux A (armature currents) feeds ADC0, mux B (tachogenerators) ADC1; both share the
 * select lines, so one select value reads the same motor's current and tacho. A sequence of
 * six conversions (125 kHz ADC clock, 104 us each, 624 us in all) runs from the ADC interrupt
 * once per tick; adc_mux_done() reports its end. */
#ifndef ADC_MUX_H
#define ADC_MUX_H

#include <stdint.h>

#include "board.h"

void adc_mux_init(void);
/* Start a sequence (from the tick interrupt); returns 0 (and does nothing) if one is running. */
uint8_t adc_mux_start(void);
/* Called from the ADC interrupt when a sequence completes, after its results were latched for
 * adc_mux_read: the application latches whatever belongs to the same sample (its tick, the
 * encoder counts), so a control step that starts after the next tick still sees one sample. */
void adc_mux_sequence_done_isr(void);
/* 1 once after each completed sequence. */
uint8_t adc_mux_take_done(void);
/* 1 while a completed sequence waits for adc_mux_take_done (call with interrupts off, before
 * sleeping, so a sequence that ends just before the sleep is not left waiting for the next tick). */
uint8_t adc_mux_done_pending(void);
/* Results of the last completed sequence: currents[i] and tachos[i] for motor i (raw codes). */
void adc_mux_read(uint16_t currents[MOTOR_COUNT], uint16_t tachos[MOTOR_COUNT]);

#endif /* ADC_MUX_H */
