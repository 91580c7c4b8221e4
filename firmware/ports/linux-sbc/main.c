/*
 * main.c - `exo-sbc`: the portable device core on a Linux single-board computer
 * (Raspberry Pi, BeagleBone, ...) wired to the exoskeleton: the four AS5048A encoders
 * on spidev, the two solenoid MOSFET gates on GPIO lines, the host over UDP.
 *
 * Start-up order puts safety first: the solenoid lines (and the heartbeat line) are
 * claimed low before anything else can fail, the core starts with both released, and
 * every exit path (error, signal, --duration) releases them again. The core toggles
 * the heartbeat line once per sample period; the external monostable it feeds drops
 * the solenoid drivers' enable 30-40 ms after the loop stops, and the kernel watchdog,
 * if present, resets the board a second or more later. See
 * docs/hardware-bringup-lab.md. The key is wiped with exo_secure_zero (the core's,
 * hmac.h), which the optimiser may not remove.
 */
#include <errno.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/random.h>
#include <time.h>
#include <unistd.h>

#include "exo_device.h"
#include "hmac.h"
#include "sbc_gpio.h"
#include "sbc_identity.h"
#include "sbc_key.h"
#include "sbc_options.h"
#include "sbc_spi.h"
#include "sbc_udp.h"
#include "sbc_watchdog.h"

#ifndef EXO_FIRMWARE_VERSION
#define EXO_FIRMWARE_VERSION "dev" /* the Makefile passes the source tree's git revision */
#endif

/* Wake this long before a sample is due and sleep the rest on the absolute
 * deadline: ppoll's timeout is relative and coarse, clock_nanosleep's is exact. */
#define SPIN_GUARD_US 200u

typedef struct {
    sbc_spi spi;
    sbc_gpio gpio;
    sbc_watchdog wd;
    sbc_udp udp;
} sbc_board;

static volatile sig_atomic_t stop_requested;

static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

static uint64_t mono_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static uint64_t b_now_us(void *ctx)
{
    (void)ctx;
    return mono_us();
}

static int b_spi(void *ctx, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n)
{
    return sbc_spi_transfer(&((sbc_board *)ctx)->spi, chip, tx, rx, n);
}

static void b_solenoids(void *ctx, int left, int right)
{
    sbc_gpio_set(&((sbc_board *)ctx)->gpio, left, right);
}

static int b_send(void *ctx, const uint8_t *data, size_t len, exo_endpoint to)
{
    return sbc_udp_send(&((sbc_board *)ctx)->udp, data, len, to);
}

static long b_receive(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from)
{
    return sbc_udp_receive(&((sbc_board *)ctx)->udp, buf, cap, from);
}

static void b_heartbeat(void *ctx, int level)
{
    sbc_gpio_heartbeat(&((sbc_board *)ctx)->gpio, level);
}

static uint32_t b_sense(void *ctx)
{
    return sbc_gpio_drivers_status(&((sbc_board *)ctx)->gpio);
}

static int b_random(void *ctx, uint8_t *out, size_t n)
{
    (void)ctx;
    /* Blocks only until the kernel's pool is first initialised (early boot). */
    ssize_t got = getrandom(out, n, 0);
    return got == (ssize_t)n ? 0 : -1;
}

static void b_kick(void *ctx)
{
    sbc_watchdog_kick(&((sbc_board *)ctx)->wd);
}

static void die(const char *msg)
{
    fprintf(stderr, "exo-sbc: %s\n", msg);
    exit(2);
}

static void go_realtime(int priority)
{
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
        fprintf(stderr, "exo-sbc: mlockall: %s (run as root or with CAP_IPC_LOCK, or pass "
                        "--no-realtime)\n", strerror(errno));
        exit(2);
    }
    struct sched_param sp;
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = priority;
    if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0) {
        fprintf(stderr, "exo-sbc: SCHED_FIFO: %s (run as root or with CAP_SYS_NICE, or pass "
                        "--no-realtime)\n", strerror(errno));
        exit(2);
    }
}

/* Wait until `deadline_us` or until a datagram arrives, whichever is first. */
static void wait_until(int sock, uint64_t deadline_us)
{
    uint64_t now = mono_us();
    if (deadline_us > now + SPIN_GUARD_US) {
        uint64_t rel = deadline_us - now - SPIN_GUARD_US;
        struct timespec ts = {(time_t)(rel / 1000000u), (long)(rel % 1000000u) * 1000L};
        struct pollfd p = {sock, POLLIN, 0};
        int r = ppoll(&p, 1, &ts, NULL);
        if (r != 0) {
            return; /* a datagram (or a signal): let the core look now */
        }
    }
    struct timespec abs = {(time_t)(deadline_us / 1000000u),
                           (long)(deadline_us % 1000000u) * 1000L};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &abs, NULL) == EINTR) {
        if (stop_requested) {
            return;
        }
    }
}

static exo_device dev; /* large: static, as on the microcontroller */

int main(int argc, char **argv)
{
    char err[256];
    sbc_options o;
    int rc = sbc_options_parse(argc, argv, &o, err, sizeof err);
    if (rc == 1) {
        fputs(sbc_usage(), stdout);
        return 0;
    }
    if (rc != 0) {
        fprintf(stderr, "exo-sbc: %s\n%s", err, sbc_usage());
        return 2;
    }

    sbc_board hw;
    memset(&hw, 0, sizeof hw);
    hw.udp.fd = -1;
    hw.wd.fd = -1;
    /* Solenoid lines first: from here on they are driven low until we decide. */
    if (sbc_gpio_open(&hw.gpio, &o, err, sizeof err) != 0) {
        die(err);
    }

    exo_config cfg;
    memset(&cfg, 0, sizeof cfg);
    if (sbc_key_load(o.key_file, cfg.key, err, sizeof err) != 0) {
        sbc_gpio_close(&hw.gpio);
        die(err);
    }
    cfg.host_ip = o.host_ip;
    cfg.sample_period_us = EXO_SAMPLE_PERIOD_US;
    cfg.bus = o.bus == SBC_BUS_DAISY_CHAIN ? EXO_BUS_DAISY_CHAIN : EXO_BUS_CHIP_SELECTS;
    cfg.rate_factor = 1;
    memcpy(cfg.firmware, SBC_FIRMWARE_NAME, sizeof SBC_FIRMWARE_NAME - 1u);
    if (o.has_device_id) {
        memcpy(cfg.unique_id, o.device_id, sizeof cfg.unique_id);
    } else if (sbc_unique_id_load(SBC_MACHINE_ID_PATH, cfg.unique_id, err, sizeof err) != 0) {
        exo_secure_zero(cfg.key, sizeof cfg.key);
        sbc_gpio_close(&hw.gpio);
        die(err);
    }

    if (sbc_spi_open(&hw.spi, &o, err, sizeof err) != 0) {
        sbc_gpio_close(&hw.gpio);
        die(err);
    }
    if (sbc_udp_open(&hw.udp, o.bind_ip, o.port, err, sizeof err) != 0) {
        sbc_spi_close(&hw.spi);
        sbc_gpio_close(&hw.gpio);
        die(err);
    }

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal; /* no SA_RESTART: waits return early with EINTR */
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGHUP, &sa, NULL);

    if (o.realtime) {
        go_realtime(o.priority);
    }

    exo_board board;
    memset(&board, 0, sizeof board);
    board.ctx = &hw;
    board.now_us = b_now_us;
    board.spi_transfer = b_spi;
    board.set_solenoids = b_solenoids;
    board.send = b_send;
    board.receive = b_receive;
    board.random_bytes = b_random;
    board.kick_watchdog = b_kick;
    board.heartbeat = b_heartbeat;
    board.sense_status = b_sense;

    /* The watchdog last: everything that can take long or fail is done. */
    int wd = sbc_watchdog_open(&hw.wd, o.watchdog, o.watchdog_timeout_s, err, sizeof err);
    if (wd < 0) {
        sbc_spi_close(&hw.spi);
        sbc_gpio_close(&hw.gpio);
        die(err);
    }
    if (!o.has_heartbeat_line) {
        fprintf(stderr, "exo-sbc: warning: no --heartbeat-line: nothing outside this program "
                        "releases the solenoids if it hangs (the kernel watchdog takes 1 s "
                        "or more); fit the heartbeat monostable before anyone wears it\n");
    }
    if (wd == 1) {
        fprintf(stderr, "exo-sbc: warning: no hardware watchdog (%s); a hung program will "
                        "not reset the board (the command watchdog still releases the "
                        "solenoids while the loop runs)\n",
                o.watchdog[0] ? o.watchdog : "--watchdog none");
    }

    if (exo_device_init(&dev, &board, &cfg) != 0) {
        sbc_watchdog_close(&hw.wd);
        sbc_spi_close(&hw.spi);
        sbc_gpio_close(&hw.gpio);
        die("the device core refused to start (no entropy for the session number?)");
    }
    /* The banner: what the bring-up profile records as the firmware version, and the
     * key id the console shows for the host's key file (equal ids, equal keys). */
    char key_id[SBC_KEY_ID_HEX + 1];
    sbc_key_id(cfg.key, sizeof cfg.key, key_id);
    exo_secure_zero(cfg.key, sizeof cfg.key);
    char uid[2 * SBC_UNIQUE_ID_BYTES + 1];
    for (unsigned i = 0; i < SBC_UNIQUE_ID_BYTES; i++) {
        snprintf(uid + 2 * i, 3, "%02x", cfg.unique_id[i]);
    }
    fprintf(stderr,
            "exo-sbc " EXO_FIRMWARE_VERSION " (%s), protocol 3: host %u.%u.%u.%u, port %u, "
            "key id %s, unique id %s (%s), %s, heartbeat %s, drivers readback %s, "
            "watchdog %s, %s\n",
            SBC_FIRMWARE_NAME, o.host_ip >> 24, (o.host_ip >> 16) & 255u,
            (o.host_ip >> 8) & 255u, o.host_ip & 255u, (unsigned)o.port, key_id, uid,
            o.has_device_id ? "--device-id" : "from /etc/machine-id",
            o.bus == SBC_BUS_DAISY_CHAIN ? "encoders: daisy chain" : "encoders: chip selects",
            o.has_heartbeat_line ? "on" : "NONE", o.has_drivers_line ? "on" : "none",
            hw.wd.fd >= 0 ? "armed" : "absent", o.realtime ? "SCHED_FIFO" : "not real-time");

    uint64_t t0 = mono_us();
    uint64_t stop_at = o.duration_s > 0 ? t0 + (uint64_t)(o.duration_s * 1e6) : UINT64_MAX;
    while (!stop_requested) {
        uint32_t wait = exo_device_poll(&dev);
        uint64_t now = mono_us();
        if (now >= stop_at) {
            break;
        }
        if (wait > 0) {
            uint64_t deadline = now + wait;
            wait_until(hw.udp.fd, deadline < stop_at ? deadline : stop_at);
        }
    }

    exo_device_stop(&dev);
    sbc_gpio_close(&hw.gpio);
    sbc_watchdog_close(&hw.wd);
    sbc_spi_close(&hw.spi);
    sbc_udp_close(&hw.udp);

    /* Every datagram the socket saw is in exactly one place: the kernel dropped it
     * (buffer full, kernel_drops) or this program read it (datagrams, empty ones
     * included), and the core counted each one it read under one of its reasons. */
    const exo_stats *s = &dev.stats;
    printf("{\"samples\": %llu, \"late\": %llu, \"lateness_max_us\": %u, \"commands\": %llu, "
           "\"stale_echo\": %llu, \"hellos\": %llu, \"joins\": %llu, \"challenges\": %llu, "
           "\"foreign\": %llu, \"flood\": %llu, \"short\": %llu, \"auth_failures\": %llu, "
           "\"replayed\": %llu, \"watchdog_releases\": %llu, \"heartbeat_edges\": %llu, "
           "\"resyncs\": %llu, \"send_errors\": %llu, \"receive_errors\": %llu, "
           "\"datagrams\": %llu, \"empty_datagrams\": %llu, \"kernel_drops\": %u, "
           "\"drivers_read_errors\": %llu}\n",
           (unsigned long long)s->samples_sent, (unsigned long long)s->late,
           (unsigned)s->lateness_max_us, (unsigned long long)s->commands,
           (unsigned long long)s->stale_echo, (unsigned long long)s->hellos,
           (unsigned long long)s->joins, (unsigned long long)s->challenges,
           (unsigned long long)s->foreign, (unsigned long long)s->flood,
           (unsigned long long)s->malformed[EXO_DROP_SHORT],
           (unsigned long long)s->malformed[EXO_DROP_AUTH], (unsigned long long)s->replayed,
           (unsigned long long)s->watchdog_releases, (unsigned long long)s->heartbeat_edges,
           (unsigned long long)s->resyncs, (unsigned long long)s->send_errors,
           (unsigned long long)s->receive_errors, (unsigned long long)hw.udp.received,
           (unsigned long long)hw.udp.empty, (unsigned)hw.udp.kernel_drops,
           (unsigned long long)hw.gpio.drivers_read_errors);
    return 0;
}
