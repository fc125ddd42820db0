/* cobs.h - Consistent Overhead Byte Stuffing (Cheshire & Baker 1999), portable C.
 * Same encoding as worm_rig_driver.protocol.codec.cobs_encode (a test checks both on the same vectors). */
#ifndef COBS_H
#define COBS_H

#include <stdint.h>

/* Encode len bytes of `in` into `out` (room for len + len / 254 + 1 bytes; no 0x00 in the
 * result, no delimiter added). Returns the encoded length. `in` and `out` must not overlap. */
uint8_t cobs_encode(const uint8_t *in, uint8_t len, uint8_t *out);

/* Decode len bytes of `in` into `out` (may be `in`: decoding in place is safe). Returns the
 * decoded length, or -1 if `in` is not valid COBS (a 0x00, or a group running past the end). */
int16_t cobs_decode(const uint8_t *in, uint8_t len, uint8_t *out);

#endif /* COBS_H */
