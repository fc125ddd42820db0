/* motors.h - three BTS7960B H-bridges on timers 4 and 5 (fast PWM, 20 kHz, 800 steps). */
#ifndef MOTORS_H
#define MOTORS_H

#include <stdint.h>

#include "board.h"

void motors_init(void);
/* Apply a signed duty (-PROTO_DUTY_FULL_SCALE..+PROTO_DUTY_FULL_SCALE) to motor i: + drives
 * RPWM (OUT1 high), - drives LPWM; 0 holds both low (brake). Returns the duty applied after
 * the PWM's resolution (what the motor gets). */
int16_t motors_set(uint8_t i, int16_t duty);
/* Enable (1) or disable (0: outputs off, PWM zeroed) every bridge at once. */
void motors_enable(uint8_t on);

#endif /* MOTORS_H */
