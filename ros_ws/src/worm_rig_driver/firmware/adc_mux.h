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
/* Start a sequence (from the tick interrupt). Ignored if one is still running. */
void adc_mux_start(void);
/* 1 once after each completed sequence. */
uint8_t adc_mux_take_done(void);
/* Results of the last sequence: currents[i] and tachos[i] for motor i (raw 10-bit codes). */
void adc_mux_read(uint16_t currents[MOTOR_COUNT], uint16_t tachos[MOTOR_COUNT]);

#endif /* ADC_MUX_H */
