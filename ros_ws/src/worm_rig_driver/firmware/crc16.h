/* crc16.h - CRC-16/XMODEM (poly 0x1021, init 0, MSB first), one byte at a time.
 *
 * On the AVR this is avr-libc's _crc_xmodem_update (util/crc16.h, hand-written
 * assembly). For the host build (the shared test vectors) the same function in
 * portable C; Python's binascii.crc_hqx(data, 0) computes the same CRC. */
#ifndef CRC16_H
#define CRC16_H

#include <stdint.h>

#ifdef __AVR__
#include <util/crc16.h>
#define crc_xmodem_update(crc, byte) _crc_xmodem_update((crc), (byte))
#else
static inline uint16_t crc_xmodem_update(uint16_t crc, uint8_t byte)
{
    crc ^= (uint16_t)byte << 8;
    for (uint8_t bit = 0; bit < 8; bit++)
        crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
    return crc;
}
#endif

static inline uint16_t crc_xmodem(const uint8_t *data, uint8_t len)
{
    uint16_t crc = 0;
    for (uint8_t i = 0; i < len; i++)
        crc = crc_xmodem_update(crc, data[i]);
    return crc;
}

#endif /* CRC16_H */
