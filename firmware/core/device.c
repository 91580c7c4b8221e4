/*
 * device.c - the device's main loop: receive and validate, learn the host, apply
 * commands under the watchdog, read the encoders, send one SAMPLE per period.
 *
 * It does what controller/sim/device_server.py (the reference device) does, decision
 * for decision, so that the host cannot tell them apart and their drop counts mean
 * the same. The board is reached only through exo_board; time only through now_us.
 */
#include "exo_device.h"

#include <string.h>

#define MAX_RATE_FACTOR 100u

static uint32_t saturate_u32(uint64_t v) { return v > 0xFFFFFFFFu ? 0xFFFFFFFFu : (uint32_t)v; }

/* Offset of sample k from the schedule's origin. With a rate factor each period holds
 * that many samples, evenly spaced (rounded to the nearest microsecond). */
static uint64_t offset_us(const exo_device *dev, uint64_t k)
{
    return (k * dev->period_us + dev->rate_factor / 2u) / dev->rate_factor;
}

static void release_solenoids(exo_device *dev)
{
    dev->locks = 0;
    if (dev->board.set_solenoids)
        dev->board.set_solenoids(dev->board.ctx, 0, 0);
}

static void ring_push(uint32_t *ring, uint64_t *n, uint32_t *max, uint64_t value)
{
    uint32_t v = saturate_u32(value);
    ring[*n % EXO_STATS_RING] = v;
    (*n)++;
    if (v > *max)
        *max = v;
}

int exo_device_init(exo_device *dev, const exo_board *board, const exo_config *cfg)
{
    memset(dev, 0, sizeof *dev); /* not running until everything below has succeeded */
    dev->board = *board;
    exo_watchdog_init(&dev->watchdog);
    release_solenoids(dev); /* first thing: whatever state the pins booted in */

    if (!board->now_us || !board->spi_transfer || !board->set_solenoids || !board->send
        || !board->receive || !board->random_bytes)
        return -1;
    uint32_t rate = cfg->rate_factor ? cfg->rate_factor : 1u;
    if (rate > MAX_RATE_FACTOR || cfg->bus > EXO_BUS_DAISY_CHAIN)
        return -1;

    dev->host_ip = cfg->host_ip;
    dev->bus = cfg->bus;
    dev->period_us = cfg->sample_period_us ? cfg->sample_period_us : EXO_SAMPLE_PERIOD_US;
    dev->rate_factor = rate;
    exo_hmac_set_key(&dev->key, cfg->key, EXO_KEY_BYTES);
    exo_peer_init(&dev->host_sessions);
    exo_as5048a_init(&dev->encoders);

    /* A fresh random session per boot is what makes commands recorded before a reboot
     * useless (they name the old one); 0 means "unknown" on the wire. */
    for (int attempt = 0; attempt < 8 && dev->session == 0; attempt++) {
        uint8_t r[8];
        if (board->random_bytes(board->ctx, r, sizeof r) != 0)
            return -1;
        dev->session = exo_le64(r);
    }
    if (dev->session == 0)
        return -1;

    dev->idle_due_us = board->now_us(board->ctx);
    dev->running = 1;
    return 0;
}

/* The host has just been learned or has changed (port or session). */
static void learn_host(exo_device *dev, exo_endpoint from, uint64_t now)
{
    if (dev->stats.host_known && from.port != dev->stats.host.port)
        dev->stats.host_changes++;
    dev->stats.host_known = 1;
    dev->stats.host = from;
    dev->have_last_host_seq = 0; /* a restarted host starts its sequence afresh */
    if (!dev->streaming) {
        /* The stream's clock starts at the first valid packet from the host: seq 0 at
         * t_us 0, so a simulated wearer gives the same data every run. */
        dev->streaming = 1;
        dev->start_us = now;
        dev->k = 0;
    }
}

static void note_round_trip(exo_device *dev, uint32_t echo, uint64_t now)
{
    uint32_t slot = echo % EXO_RTT_RING;
    uint8_t bit = (uint8_t)(1u << (slot % 8u));
    if ((dev->sent_valid[slot / 8u] & bit) && dev->sent_seq[slot] == echo) {
        ring_push(dev->stats.rtt_us, &dev->stats.rtt_n, &dev->stats.rtt_max_us,
                  now - dev->sent_at_us[slot]);
        dev->sent_valid[slot / 8u] = (uint8_t)(dev->sent_valid[slot / 8u] & ~bit);
    }
}

/* One datagram, in the reference device's order: source IP, validation (wire.c),
 * type, addressed to this boot, peer session and window, host address, then HELLO or
 * COMMAND. Every early return only counts; no state changes before the packet is
 * known to be authentic and fresh. */
static void handle(exo_device *dev, long got, exo_endpoint from, uint64_t now)
{
    exo_stats *st = &dev->stats;
    if (from.ip != dev->host_ip) {
        st->foreign++;
        return;
    }
    if ((unsigned long)got > sizeof dev->rx) {
        st->malformed[EXO_DROP_LENGTH]++; /* longer than any packet; never read */
        return;
    }
    exo_packet pkt;
    exo_drop_reason why = exo_wire_decode(&dev->key, dev->rx, (size_t)got, &pkt);
    if (why != EXO_DROP_NONE) {
        st->malformed[why]++;
        return;
    }
    if (pkt.type == EXO_TYPE_SAMPLE) {
        st->unexpected++;
        return;
    }
    /* A COMMAND must name this boot (a recorded one names an earlier boot); a HELLO
     * may not know it yet. */
    if (pkt.type == EXO_TYPE_COMMAND && pkt.receiver != dev->session) {
        st->replayed++;
        return;
    }
    exo_peer_verdict verdict = exo_peer_check(&dev->host_sessions, pkt.sender, pkt.host_seq);
    if (verdict == EXO_PEER_REPLAY) {
        st->replayed++;
        return;
    }
    if (!st->host_known || from.port != st->host.port || verdict == EXO_PEER_NEW)
        learn_host(dev, from, now);
    if (pkt.type == EXO_TYPE_HELLO) {
        /* HELLO restarts the host's sequence, so a restarted host is not "stale". It
         * never feeds the watchdog: only a COMMAND may keep a solenoid energised. */
        st->hellos++;
        dev->have_last_host_seq = 1;
        dev->last_host_seq = pkt.host_seq;
        return;
    }
    if (dev->have_last_host_seq && exo_serial_diff(pkt.host_seq, dev->last_host_seq) <= 0) {
        st->stale_commands++; /* reordered in the network: a newer one was applied */
        return;
    }
    dev->have_last_host_seq = 1;
    dev->last_host_seq = pkt.host_seq;
    dev->locks = pkt.locks;
    exo_watchdog_feed(&dev->watchdog, now);
    st->commands++;
    if (pkt.echo_valid)
        note_round_trip(dev, pkt.echo_seq, now);
}

static void receive_all(exo_device *dev)
{
    for (unsigned n = 0; n < EXO_RX_PER_POLL; n++) {
        exo_endpoint from = {0, 0};
        long got = dev->board.receive(dev->board.ctx, dev->rx, sizeof dev->rx, &from);
        if (got == 0)
            return;
        if (got < 0) {
            dev->stats.receive_errors++; /* e.g. an ICMP error report; go on */
            continue;
        }
        handle(dev, got, from, dev->board.now_us(dev->board.ctx));
    }
}

/* Status bits a board may report; the core owns SOLENOID_* and WATCHDOG_RELEASED, and
 * reserved bits must never reach the wire (they would make the sample invalid). */
#define BOARD_STATUS                                                                     \
    (EXO_STATUS_LOCKED_LEFT | EXO_STATUS_LOCKED_RIGHT | EXO_STATUS_HARD_STOP_LEFT        \
     | EXO_STATUS_HARD_STOP_RIGHT | EXO_STATUS_ENCODER_FAULT | EXO_STATUS_SUPPLY_FAULT)

/* Sample k, due at `due`: watchdog, solenoids, encoders, then build and send. */
static void tick(exo_device *dev, uint64_t due)
{
    const exo_board *b = &dev->board;
    exo_stats *st = &dev->stats;
    uint64_t now = b->now_us(b->ctx);
    int alive = exo_watchdog_check(&dev->watchdog, now);
    st->watchdog_releases = dev->watchdog.releases;
    int left = alive && (dev->locks & EXO_LOCK_LEFT);
    int right = alive && (dev->locks & EXO_LOCK_RIGHT);
    /* Solenoids before encoders: on hardware the order is immaterial (microseconds),
     * and a simulator port can advance its wearer here with this period's command,
     * as the reference device does before it reads the model. */
    b->set_solenoids(b->ctx, left, right);

    exo_sample_fields s;
    memset(&s, 0, sizeof s);
    unsigned faults = exo_as5048a_read(&dev->encoders, b, dev->bus == EXO_BUS_DAISY_CHAIN, s.counts);
    uint32_t status = b->sense_status ? b->sense_status(b->ctx) & BOARD_STATUS : 0u;
    if (left)
        status |= EXO_STATUS_SOLENOID_LEFT;
    if (right)
        status |= EXO_STATUS_SOLENOID_RIGHT;
    if (faults)
        status |= EXO_STATUS_ENCODER_FAULT;
    if (!alive)
        status |= EXO_STATUS_WATCHDOG_RELEASED;
    s.status = status;
    s.t_us = offset_us(dev, dev->k);
    s.seq = (uint32_t)dev->k; /* wraps 2^32 - 1 -> 0, as the protocol says */
    s.auth_drops = saturate_u32(st->malformed[EXO_DROP_AUTH]);
    s.replay_drops = saturate_u32(st->replayed);
    if (b->truth && b->truth(b->ctx, &s.truth) == 1)
        s.has_truth = 1;

    size_t len = exo_wire_encode_sample(&dev->key, &s, dev->session, dev->host_sessions.current,
                                        dev->tx, sizeof dev->tx);
    /* An unencodable sample (a simulator's bad truth) or a full socket buffer costs
     * this one sample; the host sees the gap in seq. Never retried. */
    if (len == 0 || b->send(b->ctx, dev->tx, len, st->host) != 0)
        st->send_errors++;

    uint64_t sent = b->now_us(b->ctx);
    uint32_t slot = s.seq % EXO_RTT_RING;
    dev->sent_seq[slot] = s.seq;
    dev->sent_at_us[slot] = sent;
    dev->sent_valid[slot / 8u] = (uint8_t)(dev->sent_valid[slot / 8u] | (1u << (slot % 8u)));

    uint64_t lateness = sent > due ? sent - due : 0;
    st->samples_sent++;
    ring_push(st->lateness_us, &st->lateness_n, &st->lateness_max_us, lateness);
    if (lateness > EXO_LATE_US)
        st->late++;
    st->streaming_us = sent - dev->start_us;
    dev->k++;
    if (b->kick_watchdog)
        b->kick_watchdog(b->ctx);
}

uint32_t exo_device_poll(exo_device *dev)
{
    if (!dev->running)
        return dev->period_us ? dev->period_us : EXO_SAMPLE_PERIOD_US;
    receive_all(dev);
    const exo_board *b = &dev->board;
    uint64_t now = b->now_us(b->ctx);

    if (!dev->streaming) {
        /* Nothing to send until the host is known; keep the hardware watchdog fed. */
        if (now >= dev->idle_due_us) {
            if (b->kick_watchdog)
                b->kick_watchdog(b->ctx);
            dev->idle_due_us += dev->period_us;
            if (dev->idle_due_us <= now)
                dev->idle_due_us = now + dev->period_us;
        }
        return (uint32_t)(dev->idle_due_us - now);
    }

    uint64_t due = dev->start_us + offset_us(dev, dev->k);
    if (now >= due) {
        if (now - due > EXO_RESYNC_US) {
            /* Stalled (a debugger, a long interrupt): rebase instead of sending a
             * burst of stale samples. */
            dev->stats.resyncs++;
            dev->start_us = now - offset_us(dev, dev->k);
            due = now;
        }
        tick(dev, due);
        now = b->now_us(b->ctx);
        due = dev->start_us + offset_us(dev, dev->k);
    }
    return now >= due ? 0u : saturate_u32(due - now);
}

void exo_device_stop(exo_device *dev)
{
    release_solenoids(dev);
    dev->running = 0;
    if (dev->streaming && dev->board.now_us)
        dev->stats.streaming_us = dev->board.now_us(dev->board.ctx) - dev->start_us;
}
