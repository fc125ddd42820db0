/* adc_mux.c - see adc_mux.h. */
#include "adc_mux.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#define STEPS (2u * MOTOR_COUNT)

static volatile uint16_t results[STEPS]; /* step 2i: current of motor i, 2i + 1: its tacho */
static volatile uint16_t ready[STEPS];   /* the last completed sequence */
static volatile uint8_t step = STEPS;     /* STEPS: idle */
static volatile uint8_t done;

static void convert(uint8_t s)
{
    /* Select first, then the ADC input: the 4051 settles in well under the 12 us before the
     * ADC's sample-and-hold closes (1.5 ADC clocks after the start). */
    MUX_PORT = (uint8_t)((MUX_PORT & ~MUX_MASK) | (s >> 1));
    ADMUX = _BV(REFS0) | ((s & 1u) ? ADC_CH_TACHOS : ADC_CH_CURRENTS); /* AVCC reference */
    ADCSRA |= _BV(ADSC);
}

void adc_mux_init(void)
{
    MUX_DDR |= MUX_MASK;
    DIDR0 = _BV(ADC0D) | _BV(ADC1D); /* no digital input buffers on the analogue pins */
    ADCSRB = 0;
    ADCSRA = _BV(ADEN) | _BV(ADIE) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0); /* 16 MHz / 128 */
}

uint8_t adc_mux_start(void)
{
    if (step < STEPS)
        return 0;
    step = 0;
    convert(0);
    return 1;
}

/* ISR_NOBLOCK: encoder edges may preempt it (see the tick ISR); a conversion takes 104 us, so
 * it cannot preempt itself. */
ISR(ADC_vect, ISR_NOBLOCK)
{
    uint8_t s = step;
    results[s] = ADC;
    s++;
    step = s;
    if (s < STEPS) {
        convert(s);
        return;
    }
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { /* adc_mux_read copies under the same lock */
        for (uint8_t k = 0; k < STEPS; k++)
            ready[k] = results[k];
    }
    adc_mux_sequence_done_isr();
    done = 1;
}

uint8_t adc_mux_take_done(void)
{
    uint8_t d;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        d = done;
        done = 0;
    }
    return d;
}

uint8_t adc_mux_done_pending(void)
{
    return done;
}

void adc_mux_read(uint16_t currents[MOTOR_COUNT], uint16_t tachos[MOTOR_COUNT])
{
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        for (uint8_t i = 0; i < MOTOR_COUNT; i++) {
            currents[i] = ready[2u * i];
            tachos[i] = ready[2u * i + 1u];
        }
    }
}
