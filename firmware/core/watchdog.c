/*
 * watchdog.c - see watchdog.h. "Alive" means the sample the latest command echoed was
 * sent at most 100 ms ago, the same comparison as the reference device
 * (now - sent_at(echo) <= WATCHDOG_S).
 */
#include "watchdog.h"

void exo_watchdog_init(exo_watchdog *w)
{
    w->fed = 0;
    w->last_cmd_us = 0;
    w->released = 1;
    w->releases = 0;
}

void exo_watchdog_feed(exo_watchdog *w, uint64_t sample_sent_us)
{
    w->fed = 1;
    w->last_cmd_us = sample_sent_us;
}

void exo_watchdog_release(exo_watchdog *w) { w->fed = 0; }

int exo_watchdog_check(exo_watchdog *w, uint64_t now_us)
{
    /* now_us >= last_cmd_us always (monotonic clock); written to stay safe if not. */
    int alive = w->fed && now_us >= w->last_cmd_us && now_us - w->last_cmd_us <= EXO_WATCHDOG_US;
    if (alive) {
        w->released = 0;
    } else {
        if (!w->released)
            w->releases++;
        w->released = 1;
    }
    return alive;
}
