/* host_vectors.c - the firmware's frame code (frame.c, cobs.c, crc16.h) compiled for the host,
 * driven by test_c_vectors.py with the same vectors as the Python codec.
 *
 *   host_vectors decode   stdin: records (uint32 little-endian length, then that many bytes),
 *                         each decoded by a fresh receiver; stdout, per record r:
 *                           F r type seq payload-hex      for every frame accepted
 *                           S r frames crc cobs length unknown oversize
 *   host_vectors encode   stdin: lines "type seq payload-hex" (decimal type and seq);
 *                         stdout: the wire bytes (COBS + 0x00) of each, in hex, one line each */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "frame.h"

static int decode(void)
{
    static frame_rx_t rx;
    unsigned char lenbuf[4];
    unsigned long record = 0;
    while (fread(lenbuf, 1, 4, stdin) == 4) {
        unsigned long len = lenbuf[0] | (lenbuf[1] << 8) | ((unsigned long)lenbuf[2] << 16) |
                            ((unsigned long)lenbuf[3] << 24);
        frame_rx_init(&rx);
        for (unsigned long i = 0; i < len; i++) {
            int c = fgetc(stdin);
            if (c == EOF) {
                fprintf(stderr, "host_vectors: record %lu truncated\n", record);
                return 2;
            }
            if (frame_rx_push(&rx, (uint8_t)c)) {
                printf("F %lu %u %u ", record, rx.type, rx.seq);
                for (uint8_t k = 0; k < rx.payload_len; k++)
                    printf("%02x", rx.payload[k]);
                printf("\n");
            }
        }
        printf("S %lu %lu %u %u %u %u %u\n", record, (unsigned long)rx.frames, rx.crc_errors, rx.cobs_errors,
               rx.length_errors, rx.unknown_types, rx.oversize);
        record++;
    }
    return 0;
}

static int encode(void)
{
    char line[1024];
    while (fgets(line, sizeof line, stdin)) {
        unsigned type, seq;
        char hex[600] = "";
        if (sscanf(line, "%u %u %599s", &type, &seq, hex) < 2) {
            fprintf(stderr, "host_vectors: bad line: %s", line);
            return 2;
        }
        uint8_t payload[PROTO_MAX_PAYLOAD_LEN];
        size_t n = strlen(hex) / 2;
        if (n > PROTO_MAX_PAYLOAD_LEN) {
            fprintf(stderr, "host_vectors: payload too long: %s", line);
            return 2;
        }
        for (size_t k = 0; k < n; k++) {
            unsigned byte;
            sscanf(hex + 2 * k, "%2x", &byte);
            payload[k] = (uint8_t)byte;
        }
        uint8_t wire[FRAME_WIRE_MAX];
        uint8_t m = frame_encode((uint8_t)type, (uint16_t)seq, payload, (uint8_t)n, wire);
        for (uint8_t k = 0; k < m; k++)
            printf("%02x", wire[k]);
        printf("\n");
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "decode") == 0)
        return decode();
    if (argc == 2 && strcmp(argv[1], "encode") == 0)
        return encode();
    fprintf(stderr, "usage: host_vectors decode|encode (see the comment at the top of host_vectors.c)\n");
    return 2;
}
