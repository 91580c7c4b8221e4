/*
 * sbc_spi_frames.h - AS5048A frames as bytes on an 8-bit SPI controller.
 *
 * Many SoC SPI controllers (the Raspberry Pi's among them) only clock 8-bit words.
 * A 16-bit frame sent most significant bit first is, on the wire, its high byte then
 * its low byte, so two 8-bit words with chip select held carry the same bits.
 */
#ifndef SBC_SPI_FRAMES_H
#define SBC_SPI_FRAMES_H

#include <stddef.h>
#include <stdint.h>

/* `n` frames to 2n bytes, high byte first. */
void sbc_frames_to_bytes(const uint16_t *frames, size_t n, uint8_t *bytes);

/* 2n bytes, high byte first, to `n` frames. */
void sbc_bytes_to_frames(const uint8_t *bytes, size_t n, uint16_t *frames);

#endif /* SBC_SPI_FRAMES_H */
