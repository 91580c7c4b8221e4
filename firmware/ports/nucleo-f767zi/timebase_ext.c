/* timebase_ext.c - the 64-bit extension of TIM2 (see timebase_ext.h). */
#include "timebase_ext.h"

#define PERIOD_SHIFT 32u
#define HALF_PERIOD (UINT64_C(1) << 31)

void tb_ext_init(tb_ext *t, uint32_t fine, uint32_t coarse)
{
    t->last_fine = fine;
    t->last_coarse = coarse;
    t->now_us = 0u;
    t->lost_wraps = 0u;
    t->mismatches = 0u;
}

uint64_t tb_ext_update(tb_ext *t, uint32_t fine, uint32_t coarse)
{
    uint32_t d_fine = fine - t->last_fine;       /* modulo 2^32: one wrap is free */
    uint32_t d_coarse = coarse - t->last_coarse; /* modulo 2^32 as well */
    uint64_t coarse_us = (uint64_t)d_coarse * TB_COARSE_TICK_US;
    /* k = round((coarse_us - d_fine) / 2^32), never negative: time does not go back. */
    uint64_t k = 0u;
    if (coarse_us + HALF_PERIOD > d_fine) {
        k = (coarse_us + HALF_PERIOD - d_fine) >> PERIOD_SHIFT;
    }
    uint64_t elapsed = (k << PERIOD_SHIFT) + d_fine;
    uint64_t diff = elapsed > coarse_us ? elapsed - coarse_us : coarse_us - elapsed;
    if (diff > TB_TOLERANCE_US) {
        t->mismatches++;
    }
    t->lost_wraps += (uint32_t)k;
    t->last_fine = fine;
    t->last_coarse = coarse;
    t->now_us += elapsed;
    return t->now_us;
}
