/* frame.h - protocol frames on a byte stream: the receiver and the encoder, portable C.
 *
 * Receiver rules (docs/protocol.md; worm_rig_driver.protocol.codec.StreamDecoder follows the same):
 *  1. bytes accumulate until a 0x00; an empty segment is ignored;
 *  2. a segment longer than PROTO_MAX_ENCODED_LEN is discarded whole (oversize);
 *  3. a segment that is not valid COBS is discarded (cobs_errors);
 *  4. a decoded frame shorter than header + CRC is discarded (length_errors);
 *  5. a CRC that does not check is discarded (crc_errors);
 *  6. an unknown type is discarded (unknown_types);
 *  7. a payload whose length differs from the table is discarded (length_errors). */
#ifndef FRAME_H
#define FRAME_H

#include <stdint.h>

#include "protocol_frames.h"

typedef struct {
    uint8_t buf[PROTO_MAX_ENCODED_LEN]; /* the segment so far; decoded in place */
    uint8_t len;
    uint8_t overflow; /* the current segment is oversize: drop it up to its delimiter */
    /* The last frame accepted (valid until the next frame_rx_push). */
    uint8_t type;
    uint16_t seq;
    const uint8_t *payload;
    uint8_t payload_len;
    /* Counters (wrap). */
    uint32_t frames;
    uint16_t crc_errors, cobs_errors, length_errors, unknown_types, oversize;
} frame_rx_t;

void frame_rx_init(frame_rx_t *rx);

/* Push one received byte; returns 1 when it completed a valid frame (see rx->type ...). */
uint8_t frame_rx_push(frame_rx_t *rx, uint8_t byte);

/* Largest frame_encode output: COBS of the largest frame plus the delimiter. */
#define FRAME_WIRE_MAX (PROTO_MAX_ENCODED_LEN + 1u)

/* Build type | seq | payload | CRC, COBS-encode it into `out` (FRAME_WIRE_MAX bytes) and add
 * the 0x00 delimiter. Returns the number of bytes to send. */
uint8_t frame_encode(uint8_t type, uint16_t seq, const void *payload, uint8_t len, uint8_t *out);

#endif /* FRAME_H */
