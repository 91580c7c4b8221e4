/*
 * timebase.h - monotonic microseconds from the CMSDK timer 0 (a 32-bit down counter at
 * the 25 MHz system clock, which wraps every 172 s). Call timebase_now_us at least once
 * per wrap (the main loop calls it every pass); under QEMU the counter follows the
 * host's clock, so it is honest time but not a real-time one.
 */
#ifndef TIMEBASE_H
#define TIMEBASE_H

#include <stdint.h>

void timebase_init(void);
uint64_t timebase_now_us(void);

/* The raw counter, for mixing into the entropy pool (its low bits jitter with the
 * host's scheduling under emulation). */
uint32_t timebase_raw(void);

#endif /* TIMEBASE_H */
