/*
 * timebase_ext.h - extend the 32-bit microsecond counter (TIM2) to 64 bits, also across
 * wraps the loop did not see.
 *
 * TIM2 counts microseconds in 32 bits and wraps every 2^32 us = 71.6 minutes. Taking
 * the difference of two reads modulo 2^32 is right as long as reads are less than one
 * wrap apart; if the loop stopped for longer (a lost wrap), the difference alone would
 * make 71.6 minutes vanish, and the core would take a command echoing a sample sent
 * 71.6 minutes ago for a fresh one. So a second, independent counter is read with it:
 * TIM5, also 32 bits, counting 500 us ticks from the same timer clock (it wraps only
 * after 24.8 days). Its coarse elapsed time picks the number k of whole TIM2 periods to
 * add: elapsed = k * 2^32 + (fine difference mod 2^32), with k the integer that brings
 * the result nearest the coarse time. The coarse time is within one tick (500 us) of the
 * truth and a TIM2 period is 2^32 us, so k is exact for any stall up to TIM5's own wrap.
 *
 * If TIM5 does not count (a wrong assumption about the chip, undetectable without a
 * board), the extension falls back to the fine difference alone, which is what it was
 * before, and counts every read that disagrees with the coarse clock in `mismatches`.
 *
 * Pure arithmetic, no registers: tested on the host (tests/test_timebase.c).
 */
#ifndef TIMEBASE_EXT_H
#define TIMEBASE_EXT_H

#include <stdint.h>

#define TB_COARSE_TICK_US 500u   /* TIM5: 96 MHz timer clock / 48000 */
#define TB_TOLERANCE_US 2000u    /* fine and coarse elapsed times agree within this */

typedef struct {
    uint32_t last_fine;   /* TIM2 at the previous read */
    uint32_t last_coarse; /* TIM5 at the previous read */
    uint64_t now_us;      /* the extended time at the previous read */
    uint32_t lost_wraps;  /* whole TIM2 periods recovered from the coarse clock */
    uint32_t mismatches;  /* reads where the two counters disagreed (TIM5 not counting?) */
} tb_ext;

/* Start at time 0 with the counters' current values. */
void tb_ext_init(tb_ext *t, uint32_t fine, uint32_t coarse);

/* The 64-bit time for a new read of both counters; never less than the previous one. */
uint64_t tb_ext_update(tb_ext *t, uint32_t fine, uint32_t coarse);

#endif /* TIMEBASE_EXT_H */
