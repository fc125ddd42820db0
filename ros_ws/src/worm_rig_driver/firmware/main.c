/* main.c - worm-gear rig firmware for the ATmega2560 (16 MHz): the rig's end of docs/protocol.md.
 *
 * Every 1 ms (timer 0) the tick interrupt snapshots the encoder counts and starts the six
 * ADC conversions; when they are done the main loop runs the control step: the command
 * watchdog, the current loops of motors in current mode, the PWM duties, and the telemetry
 * frame. In between the main loop decodes host frames from the receive ring and sleeps.
 *
 * Safety: every motor stops (duties zero, bridges disabled) PROTO_WATCHDOG_MS after the last
 * valid SETPOINT or HEARTBEAT, at the next tick: within WATCHDOG_MS + 2 ms. The hardware
 * watchdog (60 ms) resets a hung firmware, which leaves every pin an input: bridges off. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include <string.h>
#include <util/atomic.h>

#include "adc_mux.h"
#include "board.h"
#include "encoders.h"
#include "frame.h"
#include "motors.h"
#include "protocol_frames.h"
#include "uart.h"

#if F_CPU != PROTO_F_CPU
#error "F_CPU differs from the protocol table's clock"
#endif

/* Current loop (motors in current mode), in duty units (1e-4) per ADC count of error.
 * One count is 26.4 mA (ACS712-05B, 10-bit ADC); through R = 1.9 ohm that is 50 mV = 21 duty
 * units at 24 V, so the loop's static gain is ~1/21 count per unit. KP = 8 (loop gain 0.38)
 * and KI = 4 per tick (0.19 per ms) settle in ~5-10 ms with the 1 ms measurement delay and
 * stay stable for a 2x error in R or the supply. Q8 fixed point. */
#define KP_Q8 (8 * 256L)
#define KI_Q8 (4 * 256L)
#define CURRENT_DUTY_MAX 9500 /* the current loop leaves a margin to full duty */

#define STACK_PAINT 0xC5u

/* --- state ----------------------------------------------------------------------------- */
static frame_rx_t rx;
static uint16_t tx_seq;
static uint8_t link_ready;
static uint16_t expected_seq;
static uint16_t stream_divider; /* 0: not streaming */
static uint16_t stream_countdown; /* ticks to the next telemetry frame */
static uint8_t enabled;         /* bridges enabled by a SETPOINT */
static uint8_t modes;           /* bit i: motor i in current mode */
static int16_t targets[MOTOR_COUNT];
static int32_t integ[MOTOR_COUNT];
static int16_t applied[MOTOR_COUNT];
static uint32_t last_cmd_ms;
static uint16_t cmd_seq;
static uint16_t status; /* persistent bits */
static uint16_t sticky; /* bits reported once, in the next telemetry */
static uint16_t rx_seq_gaps, tx_dropped, watchdog_stops;
static volatile uint16_t tick_overruns;
static uint32_t last_stats_ms;
static uint8_t reset_flags __attribute__((section(".noinit")));

static volatile uint32_t tick_ms;           /* ms since reset */
/* A sample is the tick that started an ADC sequence and the encoder counts at that tick; it is
 * latched for the control step when its sequence completes (adc_mux_sequence_done_isr). */
static volatile uint32_t converting_ms, sample_ms;
static volatile int32_t converting_counts[MOTOR_COUNT], sample_counts[MOTOR_COUNT];

extern uint8_t _end;
extern uint8_t __stack;

/* Runs before main (and before .data/.bss init): record why we reset, stop a watchdog left
 * running by a watchdog reset, and paint the free SRAM so STATS can report the stack's reach. */
void early_init(void) __attribute__((naked, used, section(".init3")));
void early_init(void)
{
    reset_flags = MCUSR;
    MCUSR = 0;
    wdt_disable();
    for (uint8_t *p = &_end; p < (uint8_t *)SP - 8; p++)
        *p = STACK_PAINT;
}

/* Bytes above _end the stack never reached (still painted), measured 8 bytes per tick (a
 * full pass takes ~1 s): scanning all 7 kB at once would hold the control step for ~4 ms. */
static uint16_t stack_free_bytes;
static const uint8_t *stack_scan = &_end;

static void stack_scan_step(void)
{
    for (uint8_t k = 0; k < 8; k++) {
        if (stack_scan > &__stack || *stack_scan != STACK_PAINT) {
            stack_free_bytes = (uint16_t)(stack_scan - &_end);
            stack_scan = &_end;
            return;
        }
        stack_scan++;
    }
}

static uint32_t now_ms(void)
{
    uint32_t t;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { t = tick_ms; }
    return t;
}

/* --- the tick ---------------------------------------------------------------------------- */
/* ISR_NOBLOCK (interrupts re-enabled at entry): encoder edges may preempt the tick, so their
 * latency stays a few tens of cycles; the tick is 1 ms apart and cannot preempt itself. */
ISR(TIMER0_COMPA_vect, ISR_NOBLOCK)
{
    uint32_t t = tick_ms + 1u;
    tick_ms = t;
    int32_t counts[MOTOR_COUNT];
    encoders_snapshot_isr(counts); /* every tick: it extends the counts to 32 bits */
    if (adc_mux_start()) {
        converting_ms = t;
        for (uint8_t i = 0; i < MOTOR_COUNT; i++)
            converting_counts[i] = counts[i];
    } else {
        tick_overruns++; /* the last sequence is still converting: this tick has no sample */
    }
}

void adc_mux_sequence_done_isr(void)
{
    if (adc_mux_done_pending())
        tick_overruns++; /* the control step has not taken the previous sample: it is lost */
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { /* a late sequence may end while the next tick runs */
        sample_ms = converting_ms;
        for (uint8_t i = 0; i < MOTOR_COUNT; i++)
            sample_counts[i] = converting_counts[i];
    }
}

static void tick_init(void)
{
    TCCR0A = _BV(WGM01);            /* CTC */
    OCR0A = F_CPU / 64 / PROTO_SAMPLE_RATE_HZ - 1; /* 249: 16 MHz / 64 / 250 = 1 kHz exactly */
    TCCR0B = _BV(CS01) | _BV(CS00); /* / 64 */
    TIMSK0 = _BV(OCIE0A);
}

/* --- sending ----------------------------------------------------------------------------- */
static void send(uint8_t type, const void *payload, uint8_t len)
{
    uint8_t wire[FRAME_WIRE_MAX];
    tx_seq++; /* a frame dropped here still uses its seq: the host sees the gap */
    uint8_t n = frame_encode(type, tx_seq, payload, len, wire);
    if (!uart_write(wire, n)) {
        tx_dropped++;
        sticky |= STATUS_TX_DROPPED;
    }
}

static void send_error(uint16_t seq, uint8_t type, uint8_t code, int16_t detail)
{
    frame_error_t e = {.ref_seq = seq, .ref_type = type, .code = code, .detail = detail};
    send(FRAME_ERROR, &e, sizeof e);
}

static void send_ack(uint16_t seq, uint8_t type)
{
    frame_ack_t a = {.ack_seq = seq, .ack_type = type};
    send(FRAME_ACK, &a, sizeof a);
}

/* --- commands ---------------------------------------------------------------------------- */
static void stop_all(void)
{
    enabled = 0;
    for (uint8_t i = 0; i < MOTOR_COUNT; i++) {
        targets[i] = 0;
        integ[i] = 0;
        applied[i] = 0;
    }
    motors_enable(0);
    status |= STATUS_STOPPED;
}

static void on_setpoint(uint16_t seq, const frame_setpoint_t *sp)
{
    int16_t values[MOTOR_COUNT] = {sp->drive, sp->load_1, sp->load_2};
    for (uint8_t i = 0; i < MOTOR_COUNT; i++) {
        int16_t limit = (sp->mode >> i) & 1u ? PROTO_CURRENT_TARGET_LIMIT : PROTO_DUTY_FULL_SCALE;
        if (values[i] > limit || values[i] < -limit) {
            send_error(seq, FRAME_SETPOINT, ERR_OUT_OF_RANGE, values[i]);
            return;
        }
    }
    for (uint8_t i = 0; i < MOTOR_COUNT; i++) {
        if (((modes ^ sp->mode) >> i) & 1u)
            integ[i] = 0; /* a motor changing mode starts its loop afresh */
        targets[i] = values[i];
    }
    modes = sp->mode & 0x07u;
    if (!enabled) {
        enabled = 1;
        motors_enable(1);
    }
    status &= (uint16_t)~(STATUS_WATCHDOG_STOP | STATUS_STOPPED);
    last_cmd_ms = now_ms();
    cmd_seq = seq;
}

static void on_frame(void)
{
    uint8_t type = rx.type;
    uint16_t seq = rx.seq;
    if (type == FRAME_HELLO) {
        frame_hello_t hello;
        memcpy(&hello, rx.payload, sizeof hello);
        stop_all();
        stream_divider = 0;
        link_ready = 1;
        expected_seq = seq + 1u;
        status &= (uint16_t)~STATUS_WATCHDOG_STOP;
        if (hello.version != PROTO_VERSION)
            send_error(seq, type, ERR_BAD_VERSION, PROTO_VERSION);
        frame_hello_reply_t reply = {
            .version = PROTO_VERSION, .nonce = hello.nonce, .table_crc = PROTO_TABLE_CRC,
            .sample_rate_hz = PROTO_SAMPLE_RATE_HZ, .watchdog_ms = PROTO_WATCHDOG_MS,
            .pwm_top = PROTO_PWM_TOP,
        };
        send(FRAME_HELLO_REPLY, &reply, sizeof reply);
        return;
    }
    if (type >= 0x80u) { /* a rig -> host type sent to the rig */
        send_error(seq, type, ERR_UNKNOWN_TYPE, 0);
        return;
    }
    if (!link_ready) {
        send_error(seq, type, ERR_NOT_READY, 0);
        return;
    }
    if (seq != expected_seq)
        rx_seq_gaps++;
    expected_seq = seq + 1u;
    switch (type) {
    case FRAME_SETPOINT: {
        frame_setpoint_t sp;
        memcpy(&sp, rx.payload, sizeof sp);
        on_setpoint(seq, &sp);
        break;
    }
    case FRAME_HEARTBEAT:
        last_cmd_ms = now_ms();
        cmd_seq = seq;
        break;
    case FRAME_STREAM: {
        frame_stream_t st;
        memcpy(&st, rx.payload, sizeof st);
        if (st.rate_hz > PROTO_SAMPLE_RATE_HZ || (st.rate_hz && PROTO_SAMPLE_RATE_HZ % st.rate_hz)) {
            send_error(seq, type, ERR_BAD_RATE, (int16_t)st.rate_hz);
            break;
        }
        stream_divider = st.rate_hz ? PROTO_SAMPLE_RATE_HZ / st.rate_hz : 0;
        stream_countdown = 0;
        last_stats_ms = now_ms();
        send_ack(seq, type);
        break;
    }
    case FRAME_STOP:
        stop_all();
        cmd_seq = seq;
        send_ack(seq, type);
        break;
    default:
        send_error(seq, type, ERR_UNKNOWN_TYPE, 0);
        break;
    }
}

/* At most RX_BUDGET bytes per pass of the main loop: a host streaming back to back (up to 100
 * bytes per ms at 1 Mbaud) must not keep the control step from its sample. */
#define RX_BUDGET 16u

static void receive(void)
{
    int16_t c;
    for (uint8_t n = 0; n < RX_BUDGET && (c = uart_getc()) >= 0; n++) {
        uint16_t bad_before = rx.crc_errors + rx.cobs_errors + rx.length_errors + rx.oversize + rx.unknown_types;
        uint8_t got = frame_rx_push(&rx, (uint8_t)c);
        if (rx.crc_errors + rx.cobs_errors + rx.length_errors + rx.oversize + rx.unknown_types != bad_before)
            sticky |= STATUS_RX_ERROR;
        if (got)
            on_frame();
    }
}

/* --- the control step (1 kHz, after the ADC sequence) -------------------------------------- */
static int16_t current_loop(uint8_t i, int16_t measured, uint8_t *limited)
{
    int16_t error = targets[i] - measured;
    int32_t integ_max = (int32_t)CURRENT_DUTY_MAX << 8;
    int32_t in = integ[i] + KI_Q8 * error;
    if (in > integ_max)
        in = integ_max;
    if (in < -integ_max)
        in = -integ_max;
    integ[i] = in;
    int32_t u = (KP_Q8 * error + in) >> 8;
    if (u > CURRENT_DUTY_MAX || u < -CURRENT_DUTY_MAX) {
        *limited = 1;
        u = u > 0 ? CURRENT_DUTY_MAX : -CURRENT_DUTY_MAX;
    }
    return (int16_t)u;
}

static void control_step(void)
{
    uint16_t currents[MOTOR_COUNT], tachos[MOTOR_COUNT];
    int32_t counts[MOTOR_COUNT];
    uint32_t t;
    adc_mux_read(currents, tachos);
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        t = sample_ms;
        for (uint8_t i = 0; i < MOTOR_COUNT; i++)
            counts[i] = sample_counts[i];
    }

    /* Against the time now, not the sample's tick: a command may be newer than the sample. */
    if (enabled && (uint32_t)(now_ms() - last_cmd_ms) > PROTO_WATCHDOG_MS) {
        stop_all();
        status |= STATUS_WATCHDOG_STOP;
        watchdog_stops++;
    }
    uint16_t flags = 0;
    for (uint8_t i = 0; i < MOTOR_COUNT; i++) {
        int16_t duty = 0;
        if (enabled) {
            uint8_t limited = 0;
            duty = (modes >> i) & 1u ? current_loop(i, (int16_t)currents[i] - PROTO_CURRENT_ZERO_CODE, &limited)
                                     : targets[i];
            if (limited)
                flags |= i == MOTOR_DRIVE ? STATUS_DRIVE_LIMIT : STATUS_LOAD_LIMIT;
        }
        applied[i] = motors_set(i, duty);
        if (currents[i] == 0 || currents[i] >= 1023u || tachos[i] == 0 || tachos[i] >= 1023u)
            flags |= STATUS_SENSOR_FAULT;
    }
    stack_scan_step();
    static uint16_t last_encoder_errors;
    uint16_t enc_errors = encoders_errors();
    if (enc_errors != last_encoder_errors) {
        last_encoder_errors = enc_errors;
        sticky |= STATUS_ENCODER_ERROR;
    }

    if (link_ready && (status & STATUS_WATCHDOG_STOP ? (t >> 7) & 1u : 1u))
        LED_PORT |= LED_MASK;
    else
        LED_PORT &= (uint8_t)~LED_MASK;

    if (!stream_divider)
        return;
    if (stream_countdown == 0) {
        stream_countdown = stream_divider;
        frame_telemetry_t m = {
            .t_us = t * 1000u,
            .current_drive = currents[0], .current_load_1 = currents[1], .current_load_2 = currents[2],
            .tacho_drive = tachos[0], .tacho_load_1 = tachos[1], .tacho_load_2 = tachos[2],
            .count_drive = counts[0], .count_load_1 = counts[1], .count_load_2 = counts[2],
            .duty_drive = applied[0], .duty_load_1 = applied[1], .duty_load_2 = applied[2],
            .status = status | sticky | flags, .cmd_seq = cmd_seq,
        };
        sticky = 0;
        send(FRAME_TELEMETRY, &m, sizeof m);
    }
    stream_countdown--;
    if ((uint32_t)(t - last_stats_ms) >= PROTO_STATS_PERIOD_MS) {
        last_stats_ms = t;
        frame_stats_t s = {
            .uptime_ms = t, .rx_frames = rx.frames, .rx_crc_errors = rx.crc_errors,
            .rx_cobs_errors = rx.cobs_errors, .rx_length_errors = (uint16_t)(rx.length_errors + rx.unknown_types),
            .rx_oversize = rx.oversize, .rx_overruns = uart_rx_overruns(), .rx_seq_gaps = rx_seq_gaps,
            .tx_dropped = tx_dropped, .watchdog_stops = watchdog_stops, .encoder_errors = enc_errors,
            .stack_free = stack_free_bytes, .tick_overruns = tick_overruns,
        };
        send(FRAME_STATS, &s, sizeof s);
    }
}

int main(void)
{
    LED_DDR |= LED_MASK;
    if (reset_flags & _BV(WDRF))
        status |= STATUS_WDT_RESET;
    status |= STATUS_STOPPED;
    frame_rx_init(&rx);
    motors_init();
    adc_mux_init();
    encoders_init();
    uart_init();
    tick_init();
    set_sleep_mode(SLEEP_MODE_IDLE);
    wdt_enable(WDTO_60MS);
    sei();
    for (;;) {
        wdt_reset();
        if (adc_mux_take_done())
            control_step();
        receive();
        cli();
        /* Sleep only if nothing arrived since the checks above (interrupts are off here, so
         * nothing can slip in between this test and the sleep). */
        if (!uart_rx_pending() && !adc_mux_done_pending()) {
            /* sei; sleep: the instruction after sei runs first, so an interrupt that arrives
             * here still wakes the sleep instead of being missed until the next tick. */
            sleep_enable();
            sei();
            sleep_cpu();
            sleep_disable();
        }
        sei();
    }
}
