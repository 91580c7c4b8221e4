/*
 * rng.h - the true random number generator (analog noise source, 48 MHz clock from
 * the PLL's Q output): the session number drawn at every boot.
 */
#ifndef RNG_H
#define RNG_H

#include <stddef.h>
#include <stdint.h>

void rng_init(void);

/* `n` random bytes. -1 if the generator reports a seed or clock error or gives
 * nothing within a millisecond per word: then the core refuses to start. */
int rng_read(uint8_t *out, size_t n);

#endif /* RNG_H */
