/*
 * iwdg.h - the independent watchdog: clocked by the internal LSI oscillator, it resets
 * the microcontroller if the main loop stops kicking it. A reset puts every GPIO back
 * in input mode and the gate pull-downs switch the solenoids off.
 *
 * Timeout: prescaler 4, reload 445, chosen at the LSI's slowest (17 kHz, datasheet):
 * 104.9 ms at 17 kHz, 55.8 ms at 32 kHz, 37.9 ms at 47 kHz (iwdg_timing.h has the
 * numbers and their sources). The core kicks every 10 ms.
 */
#ifndef IWDG_H
#define IWDG_H

/* Start the watchdog; it cannot be stopped afterwards except by a reset. */
void iwdg_start(void);
void iwdg_kick(void);
/* 1 if the last reset came from the independent watchdog (flag then cleared). */
int iwdg_caused_reset(void);

#endif /* IWDG_H */
