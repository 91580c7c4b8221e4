/*
 * spi.h - SPI1 as the AS5048A bus master: mode 1 (CPOL 0, CPHA 1), 16-bit frames, MSB
 * first, 3 MHz (the sensor allows 10 MHz; a third of that tolerates the cable to the
 * exoskeleton), chip selects driven as plain GPIO outputs.
 */
#ifndef SPI_H
#define SPI_H

#include <stddef.h>
#include <stdint.h>

#define SPI_CHIPS 4u

void spi_init(void);

/* Clock `n` frames under one chip select assertion of `chip` (n = 1 per encoder with
 * chip selects; n = 4 for a daisy chain on chip 0). 0, or -1 on a bus timeout. */
int spi_transfer(unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n);

#endif /* SPI_H */
