/* fil_harness.c - the firmware in the loop: the real rig.elf on libsimavr, wired to a plant.
 *
 * A shared library (build/libwormfil.so) driven from Python (worm_rig_driver.fil.harness) with ctypes:
 * Python owns the plant and calls fil_step() once per plant step; this file owns the AVR:
 *
 *   UART0  <-> a pseudo-terminal whose slave is symlinked at `link`; driver_node opens that
 *              path exactly as it opens the real rig's /dev/ttyACM0. Host bytes are fed to the
 *              UART at line rate (one byte per frame time, honouring the UART's XON/XOFF);
 *              bytes the AVR sends are written to the pty master.
 *   ADC    <- the plant's analogue values per multiplexer channel; the value on ADC0 (mux A)
 *              and ADC1 (mux B) follows the select lines PC0..PC2 whenever the firmware
 *              changes them, as the two SN74HC4051 do.
 *   INT0-5 <- quadrature edges toward the plant's encoder counts, spread evenly over the step
 *              (never closer than MIN_EDGE_CYCLES: an encoder cannot outrun the firmware's ISR
 *              without losing counts, and a real one at 2000 counts/rev rarely does).
 *   PWM    -> every 100 us the duty of each bridge is read from the timers (COM bits, OCR,
 *              ICR), the port pins and the bridge enables; fil_step returns the step's mean.
 *
 * fil_cut() stops forwarding host bytes (a cut cable) and times how long the firmware takes to
 * switch every bridge off after the last byte it received.
 *
 * Register addresses come from avr-libc's own iom2560.h (the firmware's), included with
 * _SFR_* defined to give data-space addresses, as simavr's cores do. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_irq.h>
#include <sim_cycle_timers.h>
#include <avr_adc.h>
#include <avr_extint.h>
#include <avr_ioport.h>
#include <avr_uart.h>

/* Data-space addresses of the ATmega2560's registers, from avr-libc. */
#define _AVR_IO_H_
#define _SFR_IO8(x) ((x) + 0x20)
#define _SFR_IO16(x) ((x) + 0x20)
#define _SFR_MEM8(x) (x)
#define _SFR_MEM16(x) (x)
#define _SFR_MEM32(x) (x)
#include <avr/iom2560.h>

#include "board.h"

#define F_CPU_HZ 16000000u
#define MIN_EDGE_CYCLES 100u
#define DUTY_SAMPLE_CYCLES 1600u /* 100 us */
#define HOST_QUEUE 65536u
#define TX_BUFFER 65536u

typedef struct {
    uint16_t mux_a_mv[8]; /* mux A inputs (armature current sensors) [mV] */
    uint16_t mux_b_mv[8]; /* mux B inputs (tachogenerators) [mV] */
    int32_t enc_target[3]; /* encoder counts the plant reached at the end of this step */
} fil_inputs_t;

typedef struct {
    double duty[3];        /* mean signed bridge duty over the step: (RPWM - LPWM) x enable */
    uint64_t cycle;        /* AVR cycle at the end of the step */
    int32_t enc_position[3]; /* counts emitted to the pins so far */
    uint64_t host_bytes;   /* bytes delivered to the AVR's UART */
    uint64_t avr_bytes;    /* bytes the AVR sent */
    uint64_t dropped;      /* AVR bytes the pty could not take */
    int32_t state;         /* simavr cpu state (cpu_Crashed = 7 ...) */
    int32_t cut;
    uint64_t cut_last_byte_cycle; /* last host byte delivered before the cut */
    uint64_t stop_cycle;   /* first duty sample with every bridge off after the cut (0: not yet) */
} fil_outputs_t;

struct fil;
typedef struct {
    struct fil *f;
    int i;
} enc_ref_t;

typedef struct fil {
    avr_t *avr;
    int master;
    char link[512];
    /* host -> AVR */
    uint8_t *queue;
    size_t q_head, q_tail;
    int xon;
    uint32_t byte_cycles;
    /* AVR -> host */
    uint8_t *tx;
    size_t tx_len;
    /* analogue */
    fil_inputs_t in;
    uint8_t select;
    avr_irq_t *adc_irq;
    /* encoders */
    int32_t position[3];
    int32_t target[3];
    uint32_t interval[3];
    enc_ref_t enc_ref[3];
    avr_ioport_external_t ext_e, ext_d;
    /* PWM */
    double duty_sum[3];
    uint32_t duty_samples;
    fil_outputs_t out;
    int cut_pending; /* cut after the next delimiter: at a frame boundary */
} fil_t;

/* Encoder pins: A and B of each encoder: port, bit. */
static const struct { char port; uint8_t a, b; } ENC[3] = {{'E', 4, 5}, {'D', 2, 3}, {'D', 0, 1}};
/* Quadrature state of count c (mod 4): (A << 1) | B, positive sequence 00 10 11 01. */
static const uint8_t QUAD[4] = {0, 2, 3, 1};

/* --- UART ---------------------------------------------------------------------------------- */
static void on_uart_output(avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    fil_t *f = param;
    if (f->tx_len < TX_BUFFER)
        f->tx[f->tx_len++] = (uint8_t)value;
    else
        f->out.dropped++;
    f->out.avr_bytes++;
}

static void on_xon(avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    ((fil_t *)param)->xon = 1;
}

static void on_xoff(avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    ((fil_t *)param)->xon = 0;
}

/* One host byte per byte time, like the wire. */
static avr_cycle_count_t feed_uart(avr_t *avr, avr_cycle_count_t when, void *param)
{
    fil_t *f = param;
    if (f->xon && f->q_head != f->q_tail) {
        uint8_t byte = f->queue[f->q_tail];
        f->q_tail = (f->q_tail + 1) % HOST_QUEUE;
        avr_raise_irq(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT), byte);
        f->out.host_bytes++;
        f->out.cut_last_byte_cycle = avr->cycle;
        if (f->cut_pending && byte == 0) { /* the frame in flight is complete: cut here */
            f->cut_pending = 0;
            f->out.cut = 1;
            f->out.stop_cycle = 0;
            f->q_tail = f->q_head;
        }
    }
    return when + f->byte_cycles;
}

static void pump_pty(fil_t *f)
{
    uint8_t buf[4096];
    for (;;) {
        ssize_t n = read(f->master, buf, sizeof buf);
        if (n <= 0)
            break; /* EAGAIN, or EIO while the driver has the port closed */
        if (f->out.cut)
            continue; /* the cable is cut: host bytes go nowhere */
        for (ssize_t i = 0; i < n; i++) {
            size_t next = (f->q_head + 1) % HOST_QUEUE;
            if (next == f->q_tail)
                break;
            f->queue[f->q_head] = buf[i];
            f->q_head = next;
        }
    }
    size_t done = 0;
    while (done < f->tx_len) {
        ssize_t n = write(f->master, f->tx + done, f->tx_len - done);
        if (n <= 0) { /* nobody reading and the pty buffer full: lost, as on a UART */
            f->out.dropped += f->tx_len - done;
            break;
        }
        done += (size_t)n;
    }
    f->tx_len = 0;
}

/* --- ADC through the multiplexers ------------------------------------------------------------ */
static void apply_mux(fil_t *f)
{
    avr_raise_irq(f->adc_irq + ADC_IRQ_ADC0 + ADC_CH_CURRENTS, f->in.mux_a_mv[f->select & 7u]);
    avr_raise_irq(f->adc_irq + ADC_IRQ_ADC0 + ADC_CH_TACHOS, f->in.mux_b_mv[f->select & 7u]);
}

static void on_select(avr_irq_t *irq, uint32_t value, void *param)
{
    fil_t *f = param;
    uint8_t bit = (uint8_t)irq->irq; /* IOPORT_IRQ_PIN0 + n */
    f->select = (uint8_t)((f->select & ~(1u << bit)) | ((value & 1u) << bit));
    apply_mux(f);
}

/* --- encoders ---------------------------------------------------------------------------------- */
static void set_encoder_pins(fil_t *f, int i)
{
    uint8_t s = QUAD[f->position[i] & 3];
    uint8_t a = (s >> 1) & 1u, b = s & 1u;
    avr_ioport_external_t *ext = ENC[i].port == 'E' ? &f->ext_e : &f->ext_d;
    ext->value = (uint8_t)((ext->value & ~((1u << ENC[i].a) | (1u << ENC[i].b))) |
                           (a << ENC[i].a) | (b << ENC[i].b));
    /* The encoder drives the line: stronger than the firmware's pull-up. */
    avr_ioctl(f->avr, AVR_IOCTL_IOPORT_SET_EXTERNAL(ENC[i].port), ext);
    avr_irq_t *port = avr_io_getirq(f->avr, AVR_IOCTL_IOPORT_GETIRQ(ENC[i].port), 0);
    avr_raise_irq(port + ENC[i].a, a);
    avr_raise_irq(port + ENC[i].b, b);
}

static avr_cycle_count_t step_encoder(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)avr;
    enc_ref_t *ref = param;
    fil_t *f = ref->f;
    int i = ref->i;
    if (f->position[i] == f->target[i])
        return 0;
    f->position[i] += f->position[i] < f->target[i] ? 1 : -1;
    set_encoder_pins(f, i);
    return f->position[i] == f->target[i] ? 0 : when + f->interval[i];
}

/* --- PWM read-back ------------------------------------------------------------------------------- */
static uint16_t reg16(avr_t *avr, uint16_t addr)
{
    return (uint16_t)(avr->data[addr] | (avr->data[addr + 1] << 8));
}

/* Duty of one output: the compare unit's PWM if connected (COMnx1), else the PORT level. */
static double output_duty(avr_t *avr, uint16_t tccra, uint8_t com1, uint16_t ocr, uint16_t icr, uint16_t port,
                          uint8_t pin)
{
    if (avr->data[tccra] & (1u << com1)) {
        uint16_t top = reg16(avr, icr), o = reg16(avr, ocr);
        return o >= top ? 1.0 : (o + 1.0) / (top + 1.0);
    }
    return (avr->data[port] >> pin) & 1u ? 1.0 : 0.0;
}

static void bridge_duties(avr_t *avr, double duty[3])
{
    double r[3], l[3];
    r[0] = output_duty(avr, TCCR4A, COM4A1, OCR4A, ICR4, PORTH, PH3);
    l[0] = output_duty(avr, TCCR4A, COM4B1, OCR4B, ICR4, PORTH, PH4);
    r[1] = output_duty(avr, TCCR4A, COM4C1, OCR4C, ICR4, PORTH, PH5);
    l[1] = output_duty(avr, TCCR5A, COM5A1, OCR5A, ICR5, PORTL, PL3);
    r[2] = output_duty(avr, TCCR5A, COM5B1, OCR5B, ICR5, PORTL, PL4);
    l[2] = output_duty(avr, TCCR5A, COM5C1, OCR5C, ICR5, PORTL, PL5);
    uint8_t en = avr->data[PORTA] & avr->data[DDRA];
    for (int i = 0; i < 3; i++)
        duty[i] = (en >> i) & 1u ? r[i] - l[i] : 0.0;
}

static avr_cycle_count_t sample_duty(avr_t *avr, avr_cycle_count_t when, void *param)
{
    fil_t *f = param;
    double d[3];
    bridge_duties(avr, d);
    for (int i = 0; i < 3; i++)
        f->duty_sum[i] += d[i];
    f->duty_samples++;
    if (f->out.cut && !f->out.stop_cycle && d[0] == 0.0 && d[1] == 0.0 && d[2] == 0.0)
        f->out.stop_cycle = avr->cycle;
    return when + DUTY_SAMPLE_CYCLES;
}

/* simavr's default sleep callback waits in wall-clock time while the AVR sleeps; the loop in
 * Python paces rig time against the wall clock itself, so a sleeping AVR costs nothing here. */
static void no_wall_clock_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
    (void)avr;
    (void)how_long;
}

/* --- API ------------------------------------------------------------------------------------- */
void fil_destroy(fil_t *f);

fil_t *fil_create(const char *elf_path, const char *link, char *error, int error_len)
{
    fil_t *f = calloc(1, sizeof *f);
    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (!f || elf_read_firmware(elf_path, &fw) != 0) {
        snprintf(error, (size_t)error_len, "cannot read the firmware ELF %s", elf_path);
        free(f);
        return NULL;
    }
    f->master = -1;
    f->queue = malloc(HOST_QUEUE);
    f->tx = malloc(TX_BUFFER);
    f->avr = avr_make_mcu_by_name("atmega2560");
    if (!f->queue || !f->tx || !f->avr) {
        snprintf(error, (size_t)error_len, "simavr has no atmega2560 core (or out of memory)");
        fil_destroy(f);
        return NULL;
    }
    avr_t *avr = f->avr;
    avr_init(avr);
    avr->log = LOG_ERROR;
    avr_load_firmware(avr, &fw);
    avr->sleep = no_wall_clock_sleep;
    avr->frequency = F_CPU_HZ;
    avr->vcc = avr->avcc = avr->aref = 5000;

    /* The pty: the driver opens `link`. */
    f->master = posix_openpt(O_RDWR | O_NOCTTY);
    if (f->master < 0 || grantpt(f->master) || unlockpt(f->master)) {
        snprintf(error, (size_t)error_len, "cannot open a pseudo-terminal: %s", strerror(errno));
        fil_destroy(f);
        return NULL;
    }
    fcntl(f->master, F_SETFL, fcntl(f->master, F_GETFL) | O_NONBLOCK);
    snprintf(f->link, sizeof f->link, "%s", link);
    char tmp[600];
    snprintf(tmp, sizeof tmp, "%s.tmp", link);
    unlink(tmp);
    if (symlink(ptsname(f->master), tmp) || rename(tmp, link)) {
        snprintf(error, (size_t)error_len, "cannot link %s to the pty: %s", link, strerror(errno));
        fil_destroy(f);
        return NULL;
    }

    /* No console echo of the UART (simavr's default) and no usleep in the UART's status
     * polling: the bytes are the protocol's, and time is the simulation's. */
    uint32_t uart_flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &uart_flags);
    avr_irq_t *uart = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), 0);
    avr_irq_register_notify(uart + UART_IRQ_OUTPUT, on_uart_output, f);
    avr_irq_register_notify(uart + UART_IRQ_OUT_XON, on_xon, f);
    avr_irq_register_notify(uart + UART_IRQ_OUT_XOFF, on_xoff, f);
    f->xon = 1;
    /* 8N1 at 1 Mbaud: 10 us = 160 cycles per byte. */
    f->byte_cycles = F_CPU_HZ / 100000u;
    avr_cycle_timer_register(avr, f->byte_cycles, feed_uart, f);

    f->adc_irq = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, 0);
    avr_irq_t *portc = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('C'), 0);
    for (int bit = 0; bit < 3; bit++)
        avr_irq_register_notify(portc + IOPORT_IRQ_PIN0 + bit, on_select, f);

    /* INT0..INT5 start in low-level mode until the firmware configures them; simavr then polls a
     * low pin every cycle, forever. The firmware only uses edge mode, so switch that polling off. */
    for (uint8_t n = 0; n < 6; n++)
        avr_extint_set_strict_lvl_trig(avr, n, 0);
    f->ext_e.mask = (1u << 4) | (1u << 5);
    f->ext_d.mask = 0x0Fu;
    for (int i = 0; i < 3; i++) {
        f->enc_ref[i].f = f;
        f->enc_ref[i].i = i;
        set_encoder_pins(f, i);
    }
    avr_cycle_timer_register(avr, DUTY_SAMPLE_CYCLES, sample_duty, f);
    return f;
}

int fil_step(fil_t *f, uint32_t cycles, const fil_inputs_t *in, fil_outputs_t *out)
{
    avr_t *avr = f->avr;
    f->in = *in;
    apply_mux(f);
    for (int i = 0; i < 3; i++) {
        f->target[i] = in->enc_target[i];
        int64_t remaining = (int64_t)f->target[i] - f->position[i];
        if (remaining < 0)
            remaining = -remaining;
        avr_cycle_timer_cancel(avr, step_encoder, &f->enc_ref[i]);
        if (remaining) {
            uint32_t interval = cycles / (uint32_t)(remaining > cycles ? cycles : remaining);
            f->interval[i] = interval < MIN_EDGE_CYCLES ? MIN_EDGE_CYCLES : interval;
            /* Staggered so the three encoders' edges rarely coincide. */
            avr_cycle_timer_register(avr, f->interval[i] / 2u + 37u * (uint32_t)i, step_encoder, &f->enc_ref[i]);
        }
    }
    pump_pty(f);
    memset(f->duty_sum, 0, sizeof f->duty_sum);
    f->duty_samples = 0;
    avr_cycle_count_t end = avr->cycle + cycles;
    int state = avr->state;
    while (avr->cycle < end) {
        state = avr_run(avr);
        if (state == cpu_Done || state == cpu_Crashed)
            break;
    }
    pump_pty(f);
    f->out.cycle = avr->cycle;
    f->out.state = state;
    for (int i = 0; i < 3; i++) {
        f->out.enc_position[i] = f->position[i];
        f->out.duty[i] = f->duty_samples ? f->duty_sum[i] / f->duty_samples : 0.0;
    }
    *out = f->out;
    return state == cpu_Done || state == cpu_Crashed ? -1 : 0;
}

/* cut = 1: stop forwarding host bytes after the frame being delivered (at its delimiter);
 * cut = 0: forward again. */
void fil_cut(fil_t *f, int cut)
{
    if (cut) {
        f->cut_pending = 1;
    } else {
        f->cut_pending = 0;
        f->out.cut = 0;
    }
}

void fil_destroy(fil_t *f)
{
    if (!f)
        return;
    if (f->link[0])
        unlink(f->link);
    if (f->master >= 0)
        close(f->master);
    if (f->avr)
        avr_terminate(f->avr);
    free(f->queue);
    free(f->tx);
    free(f);
}
