/* frame.c - see frame.h. */
#include "frame.h"

#include <string.h>

#include "cobs.h"
#include "crc16.h"

void frame_rx_init(frame_rx_t *rx)
{
    memset(rx, 0, sizeof(*rx));
}

uint8_t frame_rx_push(frame_rx_t *rx, uint8_t byte)
{
    if (byte != 0) {
        if (rx->len < PROTO_MAX_ENCODED_LEN) {
            rx->buf[rx->len++] = byte;
        } else if (!rx->overflow) {
            rx->overflow = 1;
            rx->oversize++;
        }
        return 0;
    }
    uint8_t len = rx->len;
    uint8_t overflow = rx->overflow;
    rx->len = 0;
    rx->overflow = 0;
    if (overflow || len == 0)
        return 0;
    int16_t n = cobs_decode(rx->buf, len, rx->buf);
    if (n < 0) {
        rx->cobs_errors++;
        return 0;
    }
    if (n < (int16_t)(PROTO_HEADER_LEN + PROTO_CRC_LEN)) {
        rx->length_errors++;
        return 0;
    }
    if (crc_xmodem(rx->buf, (uint8_t)n) != 0) { /* the CRC over data + big-endian CRC is 0 */
        rx->crc_errors++;
        return 0;
    }
    int16_t expected = proto_payload_len(rx->buf[0]);
    if (expected < 0) {
        rx->unknown_types++;
        return 0;
    }
    if (n - (int16_t)(PROTO_HEADER_LEN + PROTO_CRC_LEN) != expected) {
        rx->length_errors++;
        return 0;
    }
    rx->type = rx->buf[0];
    rx->seq = (uint16_t)(rx->buf[1] | ((uint16_t)rx->buf[2] << 8));
    rx->payload = rx->buf + PROTO_HEADER_LEN;
    rx->payload_len = (uint8_t)expected;
    rx->frames++;
    return 1;
}

uint8_t frame_encode(uint8_t type, uint16_t seq, const void *payload, uint8_t len, uint8_t *out)
{
    uint8_t raw[PROTO_MAX_FRAME_LEN];
    raw[0] = type;
    raw[1] = (uint8_t)seq;
    raw[2] = (uint8_t)(seq >> 8);
    memcpy(raw + PROTO_HEADER_LEN, payload, len);
    uint8_t n = PROTO_HEADER_LEN + len;
    uint16_t crc = crc_xmodem(raw, n);
    raw[n++] = (uint8_t)(crc >> 8);
    raw[n++] = (uint8_t)crc;
    uint8_t m = cobs_encode(raw, n, out);
    out[m++] = 0;
    return m;
}
