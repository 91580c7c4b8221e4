/* rng.c - RNG registers (RM0410 "True random number generator"). */
#include "rng.h"

#include "clock.h"
#include "stm32f7_regs.h"

#define WORD_TIMEOUT_CYCLES (CLOCK_HCLK_HZ / 1000u) /* 1 ms; a word takes ~40 RNG clocks */

void rng_init(void)
{
    RCC_AHB2ENR |= RCC_AHB2ENR_RNGEN;
    (void)RCC_AHB2ENR;
    RNG_CR |= RNG_CR_RNGEN;
}

static int next_word(uint32_t *w)
{
    uint32_t start = DWT_CYCCNT;
    for (;;) {
        uint32_t sr = RNG_SR;
        if (sr & (RNG_SR_SECS | RNG_SR_CECS | RNG_SR_SEIS | RNG_SR_CEIS)) {
            /* A seed error invalidates the pending data: restart the generator and
             * let the caller fail rather than use doubtful bits. */
            RNG_SR = 0u;
            RNG_CR &= ~RNG_CR_RNGEN;
            RNG_CR |= RNG_CR_RNGEN;
            return -1;
        }
        if (sr & RNG_SR_DRDY) {
            *w = RNG_DR;
            /* A zero read can mean the data register was not yet valid (RM0410 warns
             * to check it); draw again. */
            if (*w != 0u) {
                return 0;
            }
        }
        if (DWT_CYCCNT - start > WORD_TIMEOUT_CYCLES) {
            return -1;
        }
    }
}

int rng_read(uint8_t *out, size_t n)
{
    while (n > 0u) {
        uint32_t w;
        if (next_word(&w) != 0) {
            return -1;
        }
        for (unsigned i = 0; i < 4u && n > 0u; i++, n--) {
            *out++ = (uint8_t)(w >> (8u * i));
        }
    }
    return 0;
}
