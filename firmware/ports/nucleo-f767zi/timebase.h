/*
 * timebase.h - monotonic microseconds: TIM2 (32-bit) counting at 1 MHz, extended to
 * 64 bits in software with TIM5 (32-bit, 500 us ticks) as a cross-check, so that even
 * a stall longer than TIM2's 71.6-minute wrap is measured right (timebase_ext.h).
 *
 * A stall that long cannot happen while the independent watchdog runs (it resets the
 * board within 105 ms, iwdg.h); the extension does not rely on that. Single-threaded
 * use only (no interrupts read it).
 */
#ifndef TIMEBASE_H
#define TIMEBASE_H

#include <stdint.h>

#include "timebase_ext.h"

void timebase_init(void);
uint64_t timebase_now_us(void);
/* The extension's state (lost wraps recovered, disagreements), for the console. */
const tb_ext *timebase_state(void);

#endif /* TIMEBASE_H */
