/*
 * watchdog.h - the command watchdog (protocol "Safety rules", rule 1).
 *
 * Solenoids may be energised only while valid COMMANDs keep arriving, and each one
 * holds them only until 100 ms after the device sent the sample it echoes (its own
 * clock, not the command's arrival: a command delayed on the path gets a shorter life,
 * never a longer one). Past that, both are released and every sample says
 * WATCHDOG_RELEASED until the next valid command. It is checked once per sample
 * period, so the release lands 100-110 ms after the echoed sample was sent (on
 * loopback ~98-110 ms after the last command arrived). From power-up until the first
 * command it is released.
 */
#ifndef EXO_WATCHDOG_H
#define EXO_WATCHDOG_H

#include <stdint.h>

#define EXO_WATCHDOG_US 100000u

typedef struct {
    int fed;              /* a valid COMMAND has arrived since init */
    uint64_t last_cmd_us; /* send time of the sample the latest valid COMMAND echoed */
    int released;         /* solenoids are held off (state after the last check) */
    uint64_t releases;    /* transitions from commanded to released */
} exo_watchdog;

/* Released, never fed. */
void exo_watchdog_init(exo_watchdog *w);

/* A valid COMMAND was applied; `sample_sent_us` is the send time of the sample it
 * echoes, from which its 100 ms count. (HELLO never feeds it.) */
void exo_watchdog_feed(exo_watchdog *w, uint64_t sample_sent_us);

/* A JOIN: the new session inherits no command. The next check releases (and counts
 * a release if a command was holding). */
void exo_watchdog_release(exo_watchdog *w);

/* Once per sample period: 1 if the latest command may be applied now, 0 if the
 * solenoids must be released (counting a release when this is a change). */
int exo_watchdog_check(exo_watchdog *w, uint64_t now_us);

#endif /* EXO_WATCHDOG_H */
