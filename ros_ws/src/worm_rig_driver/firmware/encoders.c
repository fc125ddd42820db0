/* encoders.c - see encoders.h.
 *
 * Each channel has its own external interrupt (INTn, any edge), so an ISR knows which channel
 * moved and decodes from the two levels alone: after an edge of A the count goes up if A != B,
 * after an edge of B it goes up if A == B (positive sequence 00 -> 10 -> 11 -> 01). The ISR
 * counts in 16 bits (about 45 cycles per edge, so the drive encoder's 139k edges/s at 436 rad/s
 * take ~40 % of the CPU, typical speeds a few %); the tick extends the counts to 32 bits every
 * millisecond, long before 16 bits can wrap (at most 139 counts per ms).
 * An edge whose channel reads the same level as at its previous edge means an edge pair came
 * too close together to be seen: counted in encoders_errors(). */
#include "encoders.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

static volatile int16_t count16[MOTOR_COUNT];
static volatile uint8_t level_a[MOTOR_COUNT], level_b[MOTOR_COUNT];
static volatile uint16_t errors;
static int16_t last16[MOTOR_COUNT]; /* tick ISR only */
static int32_t count32[MOTOR_COUNT];

#define EDGE_A(vect, i, pinreg, bit_a, bit_b) \
    ISR(vect) \
    { \
        uint8_t p = pinreg; \
        uint8_t a = (uint8_t)((p >> (bit_a)) & 1u), b = (uint8_t)((p >> (bit_b)) & 1u); \
        if (a == level_a[i]) \
            errors++; \
        level_a[i] = a; \
        if (a ^ b) \
            count16[i]++; \
        else \
            count16[i]--; \
    }

#define EDGE_B(vect, i, pinreg, bit_a, bit_b) \
    ISR(vect) \
    { \
        uint8_t p = pinreg; \
        uint8_t a = (uint8_t)((p >> (bit_a)) & 1u), b = (uint8_t)((p >> (bit_b)) & 1u); \
        if (b == level_b[i]) \
            errors++; \
        level_b[i] = b; \
        if (a ^ b) \
            count16[i]--; \
        else \
            count16[i]++; \
    }

EDGE_A(INT4_vect, MOTOR_DRIVE, PINE, PE4, PE5)
EDGE_B(INT5_vect, MOTOR_DRIVE, PINE, PE4, PE5)
EDGE_A(INT2_vect, MOTOR_LOAD_1, PIND, PD2, PD3)
EDGE_B(INT3_vect, MOTOR_LOAD_1, PIND, PD2, PD3)
EDGE_A(INT0_vect, MOTOR_LOAD_2, PIND, PD0, PD1)
EDGE_B(INT1_vect, MOTOR_LOAD_2, PIND, PD0, PD1)

void encoders_init(void)
{
    DDRE &= (uint8_t)~(_BV(PE4) | _BV(PE5));
    PORTE |= _BV(PE4) | _BV(PE5); /* pull-ups: a disconnected encoder reads a steady level */
    DDRD &= (uint8_t)~0x0Fu;
    PORTD |= 0x0Fu;
    uint8_t e = PINE, d = PIND;
    level_a[MOTOR_DRIVE] = (e >> PE4) & 1u;
    level_b[MOTOR_DRIVE] = (e >> PE5) & 1u;
    level_a[MOTOR_LOAD_1] = (d >> PD2) & 1u;
    level_b[MOTOR_LOAD_1] = (d >> PD3) & 1u;
    level_a[MOTOR_LOAD_2] = (d >> PD0) & 1u;
    level_b[MOTOR_LOAD_2] = (d >> PD1) & 1u;
    EICRA = _BV(ISC00) | _BV(ISC10) | _BV(ISC20) | _BV(ISC30); /* any edge */
    EICRB = _BV(ISC40) | _BV(ISC50);
    EIFR = 0x3Fu;
    EIMSK = 0x3Fu; /* INT0..INT5 */
}

void encoders_snapshot_isr(int32_t counts[MOTOR_COUNT])
{
    for (uint8_t i = 0; i < MOTOR_COUNT; i++) {
        int16_t c;
        ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { c = count16[i]; } /* the tick ISR can be preempted */
        count32[i] += (int16_t)(c - last16[i]); /* wraps correctly: the difference fits 16 bits */
        last16[i] = c;
        counts[i] = count32[i];
    }
}

uint16_t encoders_errors(void)
{
    uint16_t n;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { n = errors; }
    return n;
}
