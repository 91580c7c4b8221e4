/*
 * device.c - the device's main loop, protocol version 3 (docs/device-protocol.md,
 * "The device's rules"): receive and validate under a tag-check budget, answer HELLOs
 * with a single-use CHALLENGE, accept a host session only by a JOIN that answers it,
 * apply COMMANDs that advance host_seq and echo a sample sent less than 100 ms ago,
 * drive the solenoids under the watchdog, toggle the heartbeat, read the encoders,
 * send one SAMPLE per period.
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
    memcpy(dev->firmware, cfg->firmware, EXO_FIRMWARE_BYTES);
    if (!exo_firmware_valid(dev->firmware))
        return -1; /* every CHALLENGE would be invalid: the host could never join */
    memcpy(dev->unique_id, cfg->unique_id, EXO_UNIQUE_ID_BYTES);

    dev->host_ip = cfg->host_ip;
    dev->bus = cfg->bus;
    dev->period_us = cfg->sample_period_us ? cfg->sample_period_us : EXO_SAMPLE_PERIOD_US;
    dev->rate_factor = rate;
    exo_hmac_set_key(&dev->key, cfg->key, EXO_KEY_BYTES);
    exo_as5048a_init(&dev->encoders);
    exo_sent_clear(&dev->sent);

    /* A fresh random session per boot is what makes commands and JOINs recorded
     * before a reboot useless (they name the old one); 0 is never a session. */
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

static void send_to(exo_device *dev, size_t len, exo_endpoint to)
{
    if (len == 0 || dev->board.send(dev->board.ctx, dev->tx, len, to) != 0)
        dev->stats.send_errors++;
}

/* An authentic datagram of another protocol version: say which versions this device
 * speaks, at most once per second (an answer costs a tag, as the check did). */
static void answer_version(exo_device *dev, exo_endpoint from, uint64_t now)
{
    if (dev->version_sent && now - dev->last_version_us < EXO_VERSION_INTERVAL_US)
        return;
    dev->version_sent = 1;
    dev->last_version_us = now;
    size_t len = exo_wire_encode_version(&dev->key, EXO_WIRE_LOWEST_VERSION, EXO_WIRE_VERSION,
                                         dev->tx, sizeof dev->tx);
    send_to(dev, len, from);
    dev->stats.versions_sent++;
}

/* HELLO: changes nothing about the host; draws a challenge if needed, answers it.
 * Every authentic HELLO gets its CHALLENGE: the tag-check budget already bounds the
 * work, and the answer goes to the host's IP only. A rate limit shared by all sources
 * would let replayed HELLOs take every answer and keep the host from joining. */
static void on_hello(exo_device *dev, const exo_packet *pkt, exo_endpoint from, uint64_t now)
{
    exo_stats *st = &dev->stats;
    st->hellos++;
    exo_challenge *c = &dev->challenge;
    if (exo_challenge_stale(c, now)) {
        /* The old challenge dies at once, sent or not. */
        c->present = 0;
        if (dev->board.random_bytes(dev->board.ctx, c->bytes, EXO_CHALLENGE_BYTES) != 0) {
            st->random_errors++;
            return;
        }
        c->present = 1;
        c->spent = 0;
        c->drawn_us = now;
    }
    exo_challenge_fields f;
    f.hello_seq = pkt->host_seq;
    f.lifetime_ms = EXO_CHALLENGE_LIFETIME_MS;
    memcpy(f.challenge, c->bytes, EXO_CHALLENGE_BYTES);
    memcpy(f.unique_id, dev->unique_id, EXO_UNIQUE_ID_BYTES);
    memcpy(f.firmware, dev->firmware, EXO_FIRMWARE_BYTES);
    size_t len = exo_wire_encode_challenge(&dev->key, &f, dev->session, pkt->sender, dev->tx,
                                           sizeof dev->tx);
    send_to(dev, len, from);
    st->challenges++;
}

/* JOIN: the one way a host session starts (or restarts). */
static void on_join(exo_device *dev, const exo_packet *pkt, exo_endpoint from, uint64_t now)
{
    exo_stats *st = &dev->stats;
    /* Both conditions are evaluated (no early exit between them). */
    int to_me = pkt->receiver == dev->session;
    int answers = exo_challenge_accepts(&dev->challenge, pkt->join_challenge, now);
    if (!to_me || !answers) {
        st->replayed++;
        return;
    }
    dev->challenge.spent = 1;
    if (st->host_known && (from.ip != st->host.ip || from.port != st->host.port))
        st->host_changes++;
    dev->host.joined = 1;
    dev->host.session = pkt->sender;
    dev->host.last_host_seq = pkt->host_seq;
    dev->host.addr = from;
    st->host_known = 1;
    st->host = from;
    /* A new session inherits no lock: released from the next period on, watchdog
     * released, and only samples sent from now on can be echoed. */
    dev->locks = 0;
    dev->stop_heartbeat = 0;
    exo_watchdog_release(&dev->watchdog);
    exo_sent_clear(&dev->sent);
    st->joins++;
    if (!dev->streaming) {
        /* The stream starts at the first JOIN of the boot: seq 0 at t_us 0, so a
         * simulated wearer gives the same data every run. */
        dev->streaming = 1;
        dev->start_us = now;
        dev->k = 0;
    }
}

/* COMMAND: of this boot and the current host session, later than the last applied
 * one, answering a sample sent at most 100 ms ago; it holds the outputs until 100 ms
 * after that sample was sent. */
static void on_command(exo_device *dev, const exo_packet *pkt, uint64_t now)
{
    exo_stats *st = &dev->stats;
    if (pkt->receiver != dev->session || !dev->host.joined || pkt->sender != dev->host.session
        || exo_serial_diff(pkt->host_seq, dev->host.last_host_seq) <= 0) {
        st->replayed++;
        return;
    }
    int slot = exo_sent_fresh(&dev->sent, pkt->echo_seq, now);
    if (slot < 0) {
        st->stale_echo++;
        return;
    }
    dev->host.last_host_seq = pkt->host_seq;
    dev->locks = pkt->locks;
    dev->stop_heartbeat = pkt->stop_heartbeat;
    /* The watchdog counts from the echoed sample's time (its due time, at or just
     * before its send time), not from this arrival: a command held back on the path
     * gets the shorter life, never a longer one. */
    exo_watchdog_feed(&dev->watchdog, dev->sent.due_us[slot]);
    st->commands++;
    ring_push(st->rtt_us, &st->rtt_n, &st->rtt_max_us, now - dev->sent.sent_us[slot]);
}

/* One datagram through the rules in the protocol's order: source, tag-check budget,
 * validation (wire.c), type. Every early return only counts; no state changes before
 * the packet is known to be authentic and fresh. */
static void handle(exo_device *dev, long got, exo_endpoint from, uint64_t now)
{
    exo_stats *st = &dev->stats;
    if (from.ip != dev->host_ip) {
        st->foreign++;
        return;
    }
    /* Every datagram from the host's IP takes one unit of the period's budget, so at
     * most EXO_AUTH_BUDGET reach the tag check; the rest are not read at all. */
    if (dev->auth_checks >= EXO_AUTH_BUDGET) {
        st->flood++;
        return;
    }
    dev->auth_checks++;
    if ((unsigned long)got > sizeof dev->rx) {
        st->malformed[EXO_DROP_LENGTH]++; /* longer than any packet; never read */
        return;
    }
    exo_packet pkt;
    exo_drop_reason why = exo_wire_decode(&dev->key, dev->rx, (size_t)got, &pkt);
    if (why != EXO_DROP_NONE) {
        st->malformed[why]++;
        if (why == EXO_DROP_VERSION)
            answer_version(dev, from, now);
        return;
    }
    switch (pkt.type) {
    case EXO_TYPE_HELLO:
        on_hello(dev, &pkt, from, now);
        break;
    case EXO_TYPE_JOIN:
        on_join(dev, &pkt, from, now);
        break;
    case EXO_TYPE_COMMAND:
        on_command(dev, &pkt, now);
        break;
    default: /* SAMPLE, CHALLENGE, VERSION: only a device sends them */
        st->unexpected++;
    }
}

static void receive_all(exo_device *dev)
{
    for (unsigned n = 0; n < EXO_RX_PER_POLL; n++) {
        exo_endpoint from = {0, 0};
        long got = dev->board.receive(dev->board.ctx, dev->rx, sizeof dev->rx, &from);
        if (got == EXO_RX_NONE)
            return;
        if (got < 0) {
            dev->stats.receive_errors++; /* e.g. an ICMP error report; go on */
            continue;
        }
        /* got == 0 is an empty datagram: read, and counted as `short` (or foreign). */
        handle(dev, got, from, dev->board.now_us(dev->board.ctx));
    }
}

/* One heartbeat edge (boards without the pin pass NULL). */
static void heartbeat_toggle(exo_device *dev)
{
    dev->heartbeat_level = !dev->heartbeat_level;
    dev->stats.heartbeat_edges++;
    if (dev->board.heartbeat)
        dev->board.heartbeat(dev->board.ctx, dev->heartbeat_level);
}

/* Status bits a board may report; the core owns SOLENOID_*, WATCHDOG_RELEASED and
 * HEARTBEAT_STOPPED, and reserved bits must never reach the wire (they would make the
 * sample invalid). */
#define BOARD_STATUS                                                                     \
    (EXO_STATUS_LOCKED_LEFT | EXO_STATUS_LOCKED_RIGHT | EXO_STATUS_HARD_STOP_LEFT        \
     | EXO_STATUS_HARD_STOP_RIGHT | EXO_STATUS_ENCODER_FAULT | EXO_STATUS_SUPPLY_FAULT   \
     | EXO_STATUS_DRIVERS_OFF)

/* Sample k, due at `due`: watchdog, heartbeat, solenoids, encoders, then build and
 * send; a new period of tag checks begins. */
static void tick(exo_device *dev, uint64_t due)
{
    const exo_board *b = &dev->board;
    exo_stats *st = &dev->stats;
    uint64_t now = b->now_us(b->ctx);
    int alive = exo_watchdog_check(&dev->watchdog, now);
    st->watchdog_releases = dev->watchdog.releases;
    if (!alive)
        dev->stop_heartbeat = 0; /* the heartbeat resumes when the watchdog releases */
    int stopped = dev->stop_heartbeat;
    if (!stopped)
        heartbeat_toggle(dev);
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
    if (stopped)
        status |= EXO_STATUS_HEARTBEAT_STOPPED;
    s.status = status;
    s.t_us = offset_us(dev, dev->k);
    s.seq = (uint32_t)dev->k; /* wraps 2^32 - 1 -> 0, as the protocol says */
    s.auth_drops = saturate_u32(st->malformed[EXO_DROP_AUTH]);
    s.replay_drops = saturate_u32(st->replayed);
    s.stale_drops = saturate_u32(st->stale_echo);
    if (b->truth && b->truth(b->ctx, &s.truth) == 1)
        s.has_truth = 1;

    size_t len = exo_wire_encode_sample(&dev->key, &s, dev->session, dev->host.session, dev->tx,
                                        sizeof dev->tx);
    /* An unencodable sample (a simulator's bad truth) or a full socket buffer costs
     * this one sample; the host sees the gap in seq. Never retried. */
    send_to(dev, len, dev->host.addr);

    uint64_t sent = b->now_us(b->ctx);
    exo_sent_note(&dev->sent, s.seq, sent, due);

    uint64_t lateness = sent > due ? sent - due : 0;
    st->samples_sent++;
    ring_push(st->lateness_us, &st->lateness_n, &st->lateness_max_us, lateness);
    if (lateness > EXO_LATE_US)
        st->late++;
    st->streaming_us = sent - dev->start_us;
    dev->k++;
    dev->auth_checks = 0;
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
        /* Nothing to send before the first JOIN; the idle period still feeds the
         * hardware watchdog, toggles the heartbeat and renews the tag-check budget. */
        if (now >= dev->idle_due_us) {
            heartbeat_toggle(dev);
            if (b->kick_watchdog)
                b->kick_watchdog(b->ctx);
            dev->auth_checks = 0;
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
    exo_secure_zero(&dev->key, sizeof dev->key);
    exo_secure_zero(&dev->challenge, sizeof dev->challenge);
}
