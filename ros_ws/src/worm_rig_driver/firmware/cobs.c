/* cobs.c - see cobs.h. Lengths are uint8_t: every frame of the protocol is < 255 bytes. */
#include "cobs.h"

uint8_t cobs_encode(const uint8_t *in, uint8_t len, uint8_t *out)
{
    uint8_t code_at = 0; /* where the current group's code byte goes */
    uint8_t o = 1;
    uint8_t code = 1;
    for (uint8_t i = 0; i < len; i++) {
        if (in[i] != 0) {
            out[o++] = in[i];
            code++;
        }
        if (in[i] == 0 || code == 0xFF) {
            out[code_at] = code;
            code = 1;
            code_at = o;
            /* A full group that ends the data needs no (empty) group after it. */
            if (in[i] == 0 || i + 1 < len)
                o++;
        }
    }
    out[code_at] = code;
    return o;
}

int16_t cobs_decode(const uint8_t *in, uint8_t len, uint8_t *out)
{
    uint8_t i = 0, o = 0;
    while (i < len) {
        uint8_t code = in[i];
        if (code == 0 || (uint16_t)i + code > len)
            return -1;
        i++;
        for (uint8_t k = 1; k < code; k++) {
            uint8_t b = in[i++];
            if (b == 0)
                return -1;
            out[o++] = b;
        }
        if (code != 0xFF && i < len)
            out[o++] = 0;
    }
    return o;
}
