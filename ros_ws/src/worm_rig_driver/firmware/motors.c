/* motors.c - see motors.h.
 *
 * Fast PWM mode 14 (TOP = ICR = PROTO_PWM_TOP): 16 MHz / 800 = 20 kHz, inside the BTS7960B's
 * 25 kHz limit and above hearing. An output compare unit connected in fast PWM still makes a
 * one-clock spike at OCR = 0, so a zero (or full) duty disconnects the pin and holds it low
 * (or high) through PORT instead. */
#include "motors.h"

#include <avr/io.h>
#include <util/atomic.h>

#include "protocol_frames.h"

#define STEPS ((uint16_t)PROTO_PWM_TOP + 1u)
#if PROTO_PWM_TOP != 799 || PROTO_DUTY_FULL_SCALE != 10000
#error "motors_set's arithmetic assumes 800 PWM steps per 10000 duty units"
#endif

typedef struct {
    volatile uint8_t *tccra;
    volatile uint16_t *ocr;
    uint8_t com1; /* COMnx1 bit: non-inverting PWM */
    volatile uint8_t *port;
    uint8_t pin;
} pwm_out_t;

/* RPWM and LPWM of each motor (board.h). */
static const pwm_out_t OUT[MOTOR_COUNT][2] = {
    {{&TCCR4A, &OCR4A, COM4A1, &PORTH, PH3}, {&TCCR4A, &OCR4B, COM4B1, &PORTH, PH4}},
    {{&TCCR4A, &OCR4C, COM4C1, &PORTH, PH5}, {&TCCR5A, &OCR5A, COM5A1, &PORTL, PL3}},
    {{&TCCR5A, &OCR5B, COM5B1, &PORTL, PL4}, {&TCCR5A, &OCR5C, COM5C1, &PORTL, PL5}},
};

static uint16_t current_steps[MOTOR_COUNT][2];

static void set_output(uint8_t i, uint8_t side, uint16_t steps)
{
    if (current_steps[i][side] == steps)
        return; /* unchanged: spare the 1 kHz control step the register writes */
    current_steps[i][side] = steps;
    const pwm_out_t *o = &OUT[i][side];
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { /* 16-bit OCR writes share the timer's TEMP register */
        if (steps == 0 || steps >= STEPS) {
            *o->tccra &= (uint8_t)~_BV(o->com1);
            if (steps == 0)
                *o->port &= (uint8_t)~_BV(o->pin);
            else
                *o->port |= _BV(o->pin);
        } else {
            *o->ocr = steps - 1u; /* high from BOTTOM through OCR: OCR + 1 clocks */
            *o->tccra |= _BV(o->com1);
        }
    }
}

void motors_init(void)
{
    EN_PORT &= (uint8_t)~(EN_MASK(0) | EN_MASK(1) | EN_MASK(2));
    EN_DDR |= EN_MASK(0) | EN_MASK(1) | EN_MASK(2);
    PORTH &= (uint8_t)~(_BV(PH3) | _BV(PH4) | _BV(PH5));
    DDRH |= _BV(PH3) | _BV(PH4) | _BV(PH5);
    PORTL &= (uint8_t)~(_BV(PL3) | _BV(PL4) | _BV(PL5));
    DDRL |= _BV(PL3) | _BV(PL4) | _BV(PL5);
    GTCCR = _BV(TSM) | _BV(PSRSYNC); /* hold the prescalers: start both timers in step */
    ICR4 = PROTO_PWM_TOP;
    ICR5 = PROTO_PWM_TOP;
    TCCR4A = _BV(WGM41);
    TCCR5A = _BV(WGM51);
    TCCR4B = _BV(WGM43) | _BV(WGM42) | _BV(CS40);
    TCCR5B = _BV(WGM53) | _BV(WGM52) | _BV(CS50);
    TCNT4 = 0;
    TCNT5 = 0;
    GTCCR = 0;
}

int16_t motors_set(uint8_t i, int16_t duty)
{
    if (duty > PROTO_DUTY_FULL_SCALE)
        duty = PROTO_DUTY_FULL_SCALE;
    if (duty < -PROTO_DUTY_FULL_SCALE)
        duty = -PROTO_DUTY_FULL_SCALE;
    uint16_t magnitude = (uint16_t)(duty < 0 ? -duty : duty);
    /* steps = duty x 800 / 10000 = (duty x 2 + 12) / 25, rounded. The / 25 is x 41944 / 2^20,
     * which equals the integer division for every value up to 20012 (checked exhaustively):
     * a multiply costs a few tens of cycles where a division costs ~200, 3 times per ms. */
    uint16_t steps = (uint16_t)(((uint32_t)(magnitude * 2u + 12u) * 41944UL) >> 20);
    set_output(i, 0, duty > 0 ? steps : 0);
    set_output(i, 1, duty < 0 ? steps : 0);
    int16_t applied = (int16_t)((steps * 25u + 1u) >> 1); /* back to duty units: x 25 / 2 */
    return duty < 0 ? (int16_t)-applied : applied;
}

void motors_enable(uint8_t on)
{
    if (on) {
        EN_PORT |= EN_MASK(0) | EN_MASK(1) | EN_MASK(2);
    } else {
        for (uint8_t i = 0; i < MOTOR_COUNT; i++)
            motors_set(i, 0);
        EN_PORT &= (uint8_t)~(EN_MASK(0) | EN_MASK(1) | EN_MASK(2));
    }
}
