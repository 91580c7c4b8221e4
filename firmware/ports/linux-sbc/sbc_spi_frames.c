/* sbc_spi_frames.c - 16-bit frames <-> MSB-first byte pairs. */
#include "sbc_spi_frames.h"

void sbc_frames_to_bytes(const uint16_t *frames, size_t n, uint8_t *bytes)
{
    for (size_t i = 0; i < n; i++) {
        bytes[2 * i] = (uint8_t)(frames[i] >> 8);
        bytes[2 * i + 1] = (uint8_t)frames[i];
    }
}

void sbc_bytes_to_frames(const uint8_t *bytes, size_t n, uint16_t *frames)
{
    for (size_t i = 0; i < n; i++) {
        frames[i] = (uint16_t)((uint16_t)bytes[2 * i] << 8 | bytes[2 * i + 1]);
    }
}
