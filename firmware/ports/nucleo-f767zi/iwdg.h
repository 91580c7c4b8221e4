/*
 * iwdg.h - the independent watchdog: clocked by the internal 32 kHz LSI, it resets the
 * microcontroller if the main loop stops kicking it. A reset puts every GPIO back in
 * input mode and the gate pull-downs switch the solenoids off.
 *
 * Timeout: prescaler 8 (4 kHz nominal), reload 400, so 100 ms at the LSI's nominal
 * 32 kHz; the LSI may run anywhere from 17 to 47 kHz (datasheet), giving 68..188 ms.
 * The core kicks every 10 ms, so even the shortest is seven periods of margin.
 */
#ifndef IWDG_H
#define IWDG_H

/* Start the watchdog; it cannot be stopped afterwards except by a reset. */
void iwdg_start(void);
void iwdg_kick(void);
/* 1 if the last reset came from the independent watchdog (flag then cleared). */
int iwdg_caused_reset(void);

#endif /* IWDG_H */
