/*
 * test_watchdog.c - the command watchdog on its own: released from power-up, alive for
 * exactly 100 ms after the send time of the sample the command echoes (not after its
 * arrival), one release counted per lapse, HELLO-free by design (only
 * exo_watchdog_feed keeps it alive).
 */
#include "check.h"
#include "watchdog.h"

void test_watchdog(void)
{
    exo_watchdog w;
    exo_watchdog_init(&w);
    CHECK(w.released == 1);
    CHECK(exo_watchdog_check(&w, 0) == 0);
    CHECK(exo_watchdog_check(&w, 5000000) == 0);
    CHECK_EQ(w.releases, 0); /* never commanded: nothing released */

    exo_watchdog_feed(&w, 1000000);
    CHECK(exo_watchdog_check(&w, 1000000) == 1);
    CHECK(exo_watchdog_check(&w, 1000000 + EXO_WATCHDOG_US) == 1); /* 100 ms: still alive */
    CHECK(w.released == 0);
    CHECK(exo_watchdog_check(&w, 1000000 + EXO_WATCHDOG_US + 1) == 0);
    CHECK(w.released == 1);
    CHECK_EQ(w.releases, 1);
    CHECK(exo_watchdog_check(&w, 1000000 + 2 * EXO_WATCHDOG_US) == 0);
    CHECK_EQ(w.releases, 1); /* one release per lapse */

    exo_watchdog_feed(&w, 3000000);
    CHECK(exo_watchdog_check(&w, 3050000) == 1);
    CHECK(exo_watchdog_check(&w, 3200000) == 0);
    CHECK_EQ(w.releases, 2);

    /* A command that arrives 95 ms after its sample (held back on the path) holds the
     * outputs only 5 ms more: until that sample's send time + 100 ms. */
    exo_watchdog_feed(&w, 4000000); /* the echoed sample's send time; checked at 4.095 s */
    CHECK(exo_watchdog_check(&w, 4095000) == 1);
    CHECK(exo_watchdog_check(&w, 4000000 + EXO_WATCHDOG_US) == 1);
    CHECK(exo_watchdog_check(&w, 4000000 + EXO_WATCHDOG_US + 1) == 0);
    CHECK_EQ(w.releases, 3);
}
