/*
 * sbc_watchdog.h - the kernel watchdog (/dev/watchdog): once opened, the board resets
 * unless it is kicked within the timeout, so a hung or killed program (SIGKILL, OOM)
 * ends in a reset, and a reset board comes up with its solenoid gates pulled low.
 * A clean exit writes the magic 'V' first so the close disarms it (drivers built
 * with nowayout ignore this and reset anyway: then stopping the program resets the
 * board, which is still safe).
 *
 * It is not what releases a lock in time: the kernel's interface sets the timeout in
 * whole seconds (WDIOC_SETTIMEOUT), 1 s at the least, and many SoC watchdogs round
 * it up further, while the protocol wants a hung device's solenoids off within about
 * 100 ms. That is the job of the heartbeat line and the external monostable on the
 * drivers' enable (sbc_gpio.h; docs/hardware-bringup-lab.md, "Hardware release
 * (heartbeat)"), which drops the drivers 30-40 ms after the loop stops; the kernel
 * watchdog then restarts the board.
 */
#ifndef SBC_WATCHDOG_H
#define SBC_WATCHDOG_H

#include <stddef.h>

typedef struct {
    int fd; /* -1 when absent or disabled */
} sbc_watchdog;

/* Open `path` and set the timeout. 0 if armed, 1 if `path` is empty or does not exist
 * (run without; the caller warns), -1 on another error (named in `err`). */
int sbc_watchdog_open(sbc_watchdog *w, const char *path, unsigned timeout_s, char *err,
                      size_t errlen);
void sbc_watchdog_kick(sbc_watchdog *w);
/* Magic close: disarm and close. */
void sbc_watchdog_close(sbc_watchdog *w);

#endif /* SBC_WATCHDOG_H */
