/*
 * sbc_spi.h - the encoders through Linux spidev: one device node per chip select, or
 * one node for a daisy chain (chip select held low across all frames of a call).
 */
#ifndef SBC_SPI_H
#define SBC_SPI_H

#include <stddef.h>
#include <stdint.h>

#include "sbc_options.h"

typedef struct {
    int fd[SBC_MAX_SPIDEV];
    unsigned n;
    uint32_t hz;
    unsigned word_bits;
} sbc_spi;

/* Open and configure every node (mode 1, MSB first, word size, clock). 0, or -1 with
 * the node and the reason in `err`. */
int sbc_spi_open(sbc_spi *s, const sbc_options *o, char *err, size_t errlen);

/* The board's spi_transfer: `n` frames through node `chip` under one chip select
 * assertion (n is 1 with one chip select per encoder, 4 for a daisy chain). */
int sbc_spi_transfer(sbc_spi *s, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n);

void sbc_spi_close(sbc_spi *s);

#endif /* SBC_SPI_H */
