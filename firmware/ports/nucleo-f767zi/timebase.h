/*
 * timebase.h - monotonic microseconds: TIM2 (32-bit) counting at 1 MHz, extended to
 * 64 bits in software.
 *
 * The extension notices the 32-bit counter wrapping (every 71.6 minutes) when a read
 * is lower than the previous one, so it must be read at least once per wrap; the main
 * loop reads it every iteration. Single-threaded use only (no interrupts read it).
 */
#ifndef TIMEBASE_H
#define TIMEBASE_H

#include <stdint.h>

void timebase_init(void);
uint64_t timebase_now_us(void);

#endif /* TIMEBASE_H */
