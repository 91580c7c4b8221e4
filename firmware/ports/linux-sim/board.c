/*
 * board.c - the linux-sim board's functions (see board.h and exo_board.h).
 *
 * The mechanism advances once per sample period, when the core drives the solenoids
 * for that period: the plant is stepped with that command and the emulated encoders
 * take the new magnet angles, so the counts the core reads next show what the
 * command did (as on the exoskeleton, where the solenoid acts on the ratchet and the
 * encoders see the result).
 *
 * Between the firmware's solenoid outputs and the mechanism sits the model of the
 * hardware heartbeat monitor: a retriggerable monostable that holds the drivers'
 * enable for 30 ms after each edge of the heartbeat output. A solenoid is energised
 * only if the firmware drives it AND the drivers are enabled; at boot they are off
 * until the first edge. The board reads the enable back as DRIVERS_OFF.
 */
#include "board.h"

#include "wire.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <string.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <time.h>

uint64_t linux_sim_now_us(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static uint64_t now_us(void *ctx) {
    (void)ctx;
    return linux_sim_now_us();
}

static int spi_transfer(void *ctx, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n) {
    linux_sim_board *b = ctx;
    if (b->plant_failed || n == 0 || chip >= 4 || n > 4 - chip)
        return -1;
    /* One chip select per encoder (n = 1), or the daisy chain (chip 0, n = 4): every
     * chip in the chain shifts its 16 bits in the same chip-select window, so frame i
     * is chip i's. */
    for (size_t i = 0; i < n; i++)
        rx[i] = as5048a_frame(&b->chips[chip + i], tx[i]);
    b->spi_frames += n;
    return 0;
}

static void heartbeat(void *ctx, int level) {
    linux_sim_board *b = ctx;
    level = level != 0;
    if (level == b->heartbeat_level)
        return; /* no edge: the monostable is not retriggered */
    b->heartbeat_level = level;
    b->have_edge = 1;
    b->last_edge_us = linux_sim_now_us();
}

/* The monostable's output now (the enable the board reads back). */
static int drivers_enabled(linux_sim_board *b) {
    int on = b->have_edge && linux_sim_now_us() - b->last_edge_us < LINUX_SIM_HEARTBEAT_HOLD_US;
    if (b->drivers_on && !on)
        b->driver_cutoffs++;
    b->drivers_on = on;
    return on;
}

static void set_solenoids(void *ctx, int left, int right) {
    linux_sim_board *b = ctx;
    b->solenoids[0] = left != 0;
    b->solenoids[1] = right != 0;
    if (b->hold || b->plant_failed || b->plant == NULL)
        return;
    int enabled = drivers_enabled(b);
    /* --rate-factor N: each period of the wearer is sent as N samples (the last
     * reading repeated), as the Python device does. */
    if (b->drive_calls++ % (b->rate_factor ? b->rate_factor : 1u) != 0)
        return;
    uint64_t t0 = linux_sim_now_us();
    if (plant_step(b->plant, b->solenoids[0] && enabled, b->solenoids[1] && enabled,
                   &b->reading) != 0) {
        b->plant_failed = 1;
        return;
    }
    uint64_t took = linux_sim_now_us() - t0;
    if (took > b->step_max_us)
        b->step_max_us = took;
    if (took > LINUX_SIM_SLOW_STEP_US)
        b->slow_steps++;
    b->have_reading = 1;
    b->periods++;
    for (int i = 0; i < 4; i++)
        as5048a_set_magnet(&b->chips[i], b->reading.counts[i], b->reading.fault[i]);
    if (b->reading.finished)
        b->finished = 1;
}

static int send_datagram(void *ctx, const uint8_t *data, size_t len, exo_endpoint to) {
    linux_sim_board *b = ctx;
    struct sockaddr_in addr = {0};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(to.ip);
    addr.sin_port = htons(to.port);
    ssize_t r = sendto(b->sock, data, len, MSG_DONTWAIT, (struct sockaddr *)&addr, sizeof addr);
    if (r != (ssize_t)len) {
        b->send_errors++;
        return -1;
    }
    b->sends++;
    return 0;
}

static long receive_datagram(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from) {
    linux_sim_board *b = ctx;
    for (;;) {
        struct sockaddr_in addr;
        socklen_t alen = sizeof addr;
        /* MSG_TRUNC: the true length of a datagram longer than `cap`. */
        ssize_t r = recvfrom(b->sock, buf, cap, MSG_DONTWAIT | MSG_TRUNC,
                             (struct sockaddr *)&addr, &alen);
        if (r < 0) {
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                return EXO_RX_NONE;
            if (errno == EINTR || errno == ECONNREFUSED)
                continue; /* a signal, or an ICMP report about an earlier send */
            b->receive_errors++;
            return -1;
        }
        /* r == 0 is an empty datagram: handed over like any other, so the core counts
         * it (as `short`, or foreign by its source), floods of them included. */
        from->ip = ntohl(addr.sin_addr.s_addr);
        from->port = ntohs(addr.sin_port);
        return (long)r; /* the core checks the source address and counts foreign ones */
    }
}

static int random_bytes(void *ctx, uint8_t *out, size_t n) {
    (void)ctx;
    size_t got = 0;
    while (got < n) {
        ssize_t r = getrandom(out + got, n - got, 0);
        if (r < 0) {
            if (errno == EINTR)
                continue;
            return -1;
        }
        got += (size_t)r;
    }
    return 0;
}

static uint32_t sense_status(void *ctx) {
    linux_sim_board *b = ctx;
    uint32_t status = b->have_reading ? b->reading.status : 0u;
    if (!b->drivers_on)
        status |= EXO_STATUS_DRIVERS_OFF;
    return status;
}

static int truth(void *ctx, exo_truth *out) {
    linux_sim_board *b = ctx;
    if (!b->have_reading || !b->reading.has_truth)
        return 0;
    *out = b->reading.truth;
    return 1;
}

void linux_sim_board_init(linux_sim_board *ctx, exo_board *board, int sock, plant *p,
                          uint32_t host_ip) {
    memset(ctx, 0, sizeof *ctx);
    ctx->sock = sock;
    ctx->plant = p;
    ctx->host_ip = host_ip;
    for (int i = 0; i < 4; i++)
        as5048a_reset(&ctx->chips[i]);
    memset(board, 0, sizeof *board);
    board->ctx = ctx;
    board->now_us = now_us;
    board->spi_transfer = spi_transfer;
    board->set_solenoids = set_solenoids;
    board->send = send_datagram;
    board->receive = receive_datagram;
    board->random_bytes = random_bytes;
    board->kick_watchdog = NULL;
    board->sense_status = sense_status;
    board->truth = truth;
    board->heartbeat = heartbeat;
}
