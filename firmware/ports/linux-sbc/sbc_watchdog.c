/* sbc_watchdog.c - /dev/watchdog with WDIOC_KEEPALIVE and the magic close. */
#include "sbc_watchdog.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/watchdog.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <unistd.h>

int sbc_watchdog_open(sbc_watchdog *w, const char *path, unsigned timeout_s, char *err,
                      size_t errlen)
{
    w->fd = -1;
    if (path[0] == '\0') {
        return 1;
    }
    int fd = open(path, O_WRONLY | O_CLOEXEC);
    if (fd < 0) {
        if (errno == ENOENT) {
            return 1;
        }
        snprintf(err, errlen, "%s: %s%s", path, strerror(errno),
                 errno == EBUSY ? " (another program holds it, e.g. systemd's "
                                  "RuntimeWatchdogSec; or pass --watchdog none)"
                                : "");
        return -1;
    }
    w->fd = fd;
    int t = (int)timeout_s;
    if (ioctl(fd, WDIOC_SETTIMEOUT, &t) < 0) {
        /* Some drivers have a fixed timeout; running with it is still a watchdog. */
        fprintf(stderr, "exo-sbc: %s: cannot set a %u s timeout (%s); using the driver's\n",
                path, timeout_s, strerror(errno));
    }
    sbc_watchdog_kick(w);
    return 0;
}

void sbc_watchdog_kick(sbc_watchdog *w)
{
    if (w->fd >= 0) {
        int dummy = 0;
        (void)ioctl(w->fd, WDIOC_KEEPALIVE, &dummy);
    }
}

void sbc_watchdog_close(sbc_watchdog *w)
{
    if (w->fd >= 0) {
        ssize_t n = write(w->fd, "V", 1);
        (void)n;
        close(w->fd);
        w->fd = -1;
    }
}
