/* board.h - how the ATmega2560 (Arduino Mega 2560 board) is wired to the rig.
 *
 *  what                         AVR pin          Mega header   peripheral
 *  host link RX / TX            PE0 / PE1        D0 / D1       USART0 (USB via the board's 16U2)
 *  drive bridge RPWM / LPWM     PH3 / PH4        D6 / D7       OC4A / OC4B
 *  load 1 bridge RPWM / LPWM    PH5 / PL3        D8 / D46      OC4C / OC5A
 *  load 2 bridge RPWM / LPWM    PL4 / PL5        D45 / D44     OC5B / OC5C
 *  bridge enables (R_EN+L_EN)   PA0 / PA1 / PA2  D22/D23/D24   drive / load 1 / load 2
 *  mux select S0 S1 S2 (both)   PC0 / PC1 / PC2  D37/D36/D35   SN74HC4051 x2, INH tied low
 *  mux A common (currents)      PF0              A0            ADC0: ch0 drive, ch1 load 1, ch2 load 2
 *  mux B common (tachos)        PF1              A1            ADC1: ch0 drive, ch1 load 1, ch2 load 2
 *  drive encoder A / B          PE4 / PE5        D2 / D3       INT4 / INT5
 *  load 1 encoder A / B         PD2 / PD3        D19 / D18     INT2 / INT3
 *  load 2 encoder A / B         PD0 / PD1        D21 / D20     INT0 / INT1 (the board's I2C pull-ups are harmless)
 *  status LED                   PB7              D13           on: link up; blinks: watchdog stop
 *
 * BTS7960B: RPWM high drives OUT1 to the supply (motor +), LPWM high drives OUT2; both low brakes;
 * R_EN/L_EN low leaves both half-bridges off (outputs high-impedance).
 */
#ifndef BOARD_H
#define BOARD_H

#define MOTOR_COUNT 3
#define MOTOR_DRIVE 0
#define MOTOR_LOAD_1 1
#define MOTOR_LOAD_2 2

#define EN_DDR DDRA
#define EN_PORT PORTA
#define EN_MASK(i) (1u << (i)) /* PA0..PA2 */

#define MUX_DDR DDRC
#define MUX_PORT PORTC
#define MUX_MASK 0x07u /* PC0..PC2 */

#define ADC_CH_CURRENTS 0 /* ADC0: mux A */
#define ADC_CH_TACHOS 1 /* ADC1: mux B */

#define LED_DDR DDRB
#define LED_PORT PORTB
#define LED_MASK (1u << 7)

#endif /* BOARD_H */
