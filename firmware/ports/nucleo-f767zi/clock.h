/*
 * clock.h - the system clock: 96 MHz from the PLL.
 *
 * 96 MHz, not the F767's 216 MHz maximum, on purpose: it needs neither the voltage
 * regulator's over-drive mode nor more than 3 flash wait states, and the device's work
 * per 10 ms period (about ten HMAC-SHA256 blocks, eight SPI frames, a few frames) takes
 * a small fraction of it. The PLL's Q output gives the 48 MHz the RNG needs.
 *
 * Source: HSE in bypass mode (the Nucleo's ST-LINK drives OSC_IN with 8 MHz); if that
 * clock does not start (solder bridges changed, ST-LINK cut off), the 16 MHz internal
 * oscillator is used instead, with the same resulting frequencies.
 */
#ifndef CLOCK_H
#define CLOCK_H

#include <stdint.h>

#define CLOCK_HCLK_HZ 96000000u
#define CLOCK_PCLK1_HZ 48000000u  /* APB1 (max 54 MHz): TIM2 runs at 2x = 96 MHz */
#define CLOCK_PCLK2_HZ 96000000u  /* APB2 (max 108 MHz): SPI1 */

typedef enum { CLOCK_FROM_HSE = 0, CLOCK_FROM_HSI = 1, CLOCK_FAILED = 2 } clock_source;

clock_source clock_init(void);

/* Busy-wait for at least `cycles` CPU cycles (DWT cycle counter). */
void clock_delay_cycles(uint32_t cycles);

#endif /* CLOCK_H */
