/*
 * test_device.c - the device loop against the fake board, rule by rule of the
 * protocol's "The device's rules": start-up (solenoids released, entropy and a valid
 * identity required), source and tag-check budget (flood), HELLO -> CHALLENGE (every
 * one answered, redraw), JOIN (receiver, challenge equal / spent / expired, release, ring
 * cleared, stream start), COMMAND (replay, stale_echo, apply), VERSION answers, the
 * heartbeat and its status bits, the watchdog, the 32-bit sequence and 64-bit clock
 * wraps, timing, the rate-factor probe, ground truth, and stop.
 */
#include <string.h>

#include "check.h"
#include "exo_device.h"
#include "fake_board.h"

#define HOST_IP 0x7F000001u /* 127.0.0.1 */
#define HOST_PORT 50000u
#define OTHER_IP 0x7F000002u
#define HOST_SESSION 0x0123456789abcdefu
#define PERIOD EXO_SAMPLE_PERIOD_US

static fake_board fb;
static exo_device dev; /* static, as a port allocates it */
static exo_board board;
static exo_config cfg;
static exo_hmac_key key;
static uint32_t host_seq;

static void setup(int optional, int daisy)
{
    fake_init(&fb);
    fb.daisy_chain = daisy;
    board = fake_interface(&fb, optional);
    memset(&cfg, 0, sizeof cfg);
    for (unsigned i = 0; i < EXO_KEY_BYTES; i++)
        cfg.key[i] = (uint8_t)(0x40u + i);
    cfg.host_ip = HOST_IP;
    cfg.bus = daisy ? EXO_BUS_DAISY_CHAIN : EXO_BUS_CHIP_SELECTS;
    for (unsigned i = 0; i < 16; i++)
        cfg.unique_id[i] = (uint8_t)(0x30u + i);
    memcpy(cfg.firmware, "exo-test 3", 10);
    exo_hmac_set_key(&key, cfg.key, EXO_KEY_BYTES);
    host_seq = 0;
}

static int start(void) { return exo_device_init(&dev, &board, &cfg); }

static void push_hello_from(uint64_t session, uint32_t ip, uint16_t port)
{
    uint8_t d[EXO_MAX_PACKET];
    size_t n = exo_wire_encode_hello(&key, ++host_seq, session, 0, d, sizeof d);
    fake_push(&fb, d, (long)n, ip, port);
}

static void push_join_full(uint64_t session, uint64_t to, uint32_t seq, const uint8_t *challenge,
                           uint32_t ip, uint16_t port)
{
    uint8_t d[EXO_MAX_PACKET];
    size_t n = exo_wire_encode_join(&key, seq, challenge, session, to, d, sizeof d);
    fake_push(&fb, d, (long)n, ip, port);
}

static void push_command_full(uint64_t session, uint64_t to, uint32_t seq, uint32_t echo,
                              unsigned locks, int stop_hb, uint32_t ip, uint16_t port)
{
    uint8_t d[EXO_MAX_PACKET];
    size_t n = exo_wire_encode_command(&key, seq, echo, locks, stop_hb, session, to, d, sizeof d);
    fake_push(&fb, d, (long)n, ip, port);
}

/* Decode the latest datagram of `type` among the device's last 3 sends (a poll may
 * send a CHALLENGE and then a SAMPLE); 0 if none or invalid. */
static int last_of_type(exo_packet *p, unsigned type)
{
    for (unsigned back = 0; back < 3 && back < fb.n_sent; back++) {
        const fake_datagram *d = &fb.sent[(fb.n_sent - 1u - back) % FAKE_QUEUE];
        if (exo_wire_decode(&key, d->data, (size_t)d->len, p) == EXO_DROP_NONE && p->type == type)
            return 1;
    }
    return 0;
}

static int last_sample(exo_packet *p) { return last_of_type(p, EXO_TYPE_SAMPLE); }

/* The latest sample sent (the one a host answers), or NULL. */
static const fake_datagram *last_sample_sent(uint32_t *seq)
{
    for (unsigned back = 0; back < FAKE_QUEUE && back < fb.n_sent; back++) {
        const fake_datagram *d = &fb.sent[(fb.n_sent - 1u - back) % FAKE_QUEUE];
        exo_packet p;
        if (exo_wire_decode(&key, d->data, (size_t)d->len, &p) == EXO_DROP_NONE
            && p.type == EXO_TYPE_SAMPLE) {
            *seq = p.sample.seq;
            return d;
        }
    }
    return NULL;
}

/* seq of the latest sample sent. */
static uint32_t last_seq(void)
{
    uint32_t seq = 0xDEADBEEFu;
    (void)last_sample_sent(&seq);
    return seq;
}

/* The latest sample's time on the device clock: its t_us from the stream's origin
 * (no resync in these tests), at or before its send time. The watchdog counts a
 * command's 100 ms from the time of the sample it echoes. */
static uint64_t last_sample_at(void)
{
    uint32_t seq;
    const fake_datagram *d = last_sample_sent(&seq);
    exo_packet p;
    if (!d || exo_wire_decode(&key, d->data, (size_t)d->len, &p) != EXO_DROP_NONE)
        return 0;
    CHECK(dev.start_us + p.sample.t_us <= (uint64_t)d->at_us);
    return dev.start_us + p.sample.t_us;
}

/* The host's command answering the latest sample. */
static void push_command(unsigned locks)
{
    push_command_full(HOST_SESSION, dev.session, ++host_seq, last_seq(), locks, 0, HOST_IP,
                      HOST_PORT);
}

/* Move the clock by `us` in 1 ms steps, polling at each (a port polling often). */
static void run_for(uint64_t us)
{
    for (uint64_t t = 0; t < us; t += 1000) {
        fb.now += 1000;
        exo_device_poll(&dev);
    }
}

/* HELLO, take the CHALLENGE, JOIN with it: 1 if the device accepted the JOIN. */
static int join(uint64_t session, uint16_t port)
{
    uint64_t joins = dev.stats.joins;
    push_hello_from(session, HOST_IP, port);
    exo_device_poll(&dev);
    exo_packet c;
    if (!last_of_type(&c, EXO_TYPE_CHALLENGE))
        return 0;
    push_join_full(session, dev.session, ++host_seq, c.challenge.challenge, HOST_IP, port);
    exo_device_poll(&dev);
    return dev.stats.joins == joins + 1;
}

static void startup(void)
{
    setup(1, 0);
    fb.left = fb.right = 1; /* as if the pins came up energised */
    CHECK_EQ(start(), 0);
    CHECK_EQ(fb.solenoid_calls, 1); /* released first thing */
    CHECK(fb.left == 0 && fb.right == 0);
    CHECK_EQ(dev.session, 0xA7A6A5A4A3A2A1A0u); /* from the board's random bytes */
    CHECK(dev.watchdog.released == 1);

    /* No host yet: nothing sent, encoders and solenoids untouched, hardware watchdog
     * kicked and heartbeat toggled once per idle period. */
    uint32_t wait = exo_device_poll(&dev);
    CHECK(wait > 0 && wait <= PERIOD);
    unsigned edges = fb.heartbeat_edges;
    run_for(100000);
    CHECK_EQ(fb.n_sent, 0);
    CHECK_EQ(fb.spi_calls, 0);
    CHECK_EQ(fb.solenoid_calls, 1);
    CHECK(fb.kicks >= 10 && fb.kicks <= 11);
    CHECK_EQ(fb.heartbeat_edges - edges, 10);

    /* A device never initialised (zeroed, as static storage is) stays inert. */
    memset(&dev, 0, sizeof dev);
    CHECK_EQ(exo_device_poll(&dev), PERIOD);
    exo_device_stop(&dev);

    /* A session of 0 from the RNG is drawn again. */
    setup(0, 0);
    fb.random_zero_draws = 2;
    CHECK_EQ(start(), 0);
    CHECK(dev.session != 0);

    /* No entropy: refuse to start, solenoids released, and poll stays inert even
     * with an authentic host talking to it. */
    setup(0, 0);
    fb.left = 1;
    fb.random_fail = 1;
    CHECK_EQ(start(), -1);
    CHECK(fb.left == 0 && fb.right == 0);
    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    run_for(50000);
    CHECK_EQ(fb.n_sent, 0);
    CHECK_EQ(fb.energise_calls, 0);

    /* A board without a required function, a rate factor out of range, a firmware
     * name the CHALLENGE could not carry. */
    setup(0, 0);
    board.send = NULL;
    CHECK_EQ(start(), -1);
    setup(0, 0);
    cfg.rate_factor = 101;
    CHECK_EQ(start(), -1);
    cfg.rate_factor = 100;
    CHECK_EQ(start(), 0);
    setup(0, 0);
    memset(cfg.firmware, 0, sizeof cfg.firmware);
    CHECK_EQ(start(), -1);
    cfg.firmware[0] = 'x';
    cfg.firmware[2] = 'y'; /* not NUL-padded */
    CHECK_EQ(start(), -1);
    memcpy(cfg.firmware, "exo\tx", 5);
    CHECK_EQ(start(), -1);
    memcpy(cfg.firmware, "0123456789abcdef", 16); /* 16 characters, no NUL: valid */
    CHECK_EQ(start(), 0);
}

/* HELLO draws a challenge and changes nothing else; the CHALLENGE goes to the HELLO's
 * source; every authentic HELLO within the budget is answered (no rate limit an
 * attacker's replayed HELLOs could use up); a challenge older than 500 ms, or spent,
 * is redrawn. */
static void hello_and_challenge(void)
{
    setup(1, 0);
    CHECK_EQ(start(), 0);

    /* From another IP: ignored and counted, however authentic. */
    push_hello_from(HOST_SESSION, OTHER_IP, HOST_PORT);
    run_for(20000);
    CHECK_EQ(dev.stats.foreign, 1);
    CHECK_EQ(fb.n_sent, 0);

    /* Forged (wrong tag) from the right IP: counted, not answered. */
    uint8_t d[EXO_MAX_PACKET];
    size_t n = exo_wire_encode_hello(&key, 1, HOST_SESSION, 0, d, sizeof d);
    d[n - 1] ^= 0x80;
    fake_push(&fb, d, (long)n, HOST_IP, HOST_PORT);
    run_for(10000);
    CHECK_EQ(dev.stats.malformed[EXO_DROP_AUTH], 1);
    CHECK_EQ(fb.n_sent, 0);

    /* An authentic HELLO: a CHALLENGE to its source, naming it; no stream. */
    uint64_t hello_at = fb.now;
    push_hello_from(HOST_SESSION, HOST_IP, 40001);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.hellos, 1);
    CHECK_EQ(dev.stats.challenges, 1);
    CHECK_EQ(fb.n_sent, 1);
    exo_packet c;
    CHECK(last_of_type(&c, EXO_TYPE_CHALLENGE));
    CHECK_EQ(fake_last_sent(&fb)->peer.ip, HOST_IP);
    CHECK_EQ(fake_last_sent(&fb)->peer.port, 40001);
    CHECK_EQ(c.sender, dev.session);
    CHECK_EQ(c.receiver, HOST_SESSION);
    CHECK_EQ(c.challenge.hello_seq, host_seq);
    CHECK_EQ(c.challenge.lifetime_ms, 1000);
    CHECK(memcmp(c.challenge.challenge, dev.challenge.bytes, 16) == 0);
    CHECK(memcmp(c.challenge.unique_id, cfg.unique_id, 16) == 0);
    CHECK(memcmp(c.challenge.firmware, "exo-test 3\0\0\0\0\0\0", 16) == 0);
    CHECK_EQ(dev.streaming, 0);
    CHECK_EQ(dev.stats.host_known, 0);
    uint8_t first[16];
    memcpy(first, c.challenge.challenge, 16);

    /* A replayed HELLO from another port and the host's own, 1 us later in the same
     * period: both answered, each to its source, with the same challenge (not 500 ms
     * old), so a replayer cannot take the host's answer away. */
    fb.now = hello_at + 1;
    push_hello_from(0x5555u, HOST_IP, 40002); /* any session may ask */
    push_hello_from(HOST_SESSION, HOST_IP, 40001);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.hellos, 3);
    CHECK_EQ(dev.stats.challenges, 3);
    CHECK_EQ(fb.n_sent, 3);
    CHECK(last_of_type(&c, EXO_TYPE_CHALLENGE));
    CHECK_EQ(fake_last_sent(&fb)->peer.port, 40001);
    CHECK_EQ(c.receiver, HOST_SESSION);
    CHECK(memcmp(c.challenge.challenge, first, 16) == 0);
    const fake_datagram *other = &fb.sent[(fb.n_sent - 2u) % FAKE_QUEUE];
    exo_packet o;
    CHECK(exo_wire_decode(&key, other->data, (size_t)other->len, &o) == EXO_DROP_NONE);
    CHECK_EQ(other->peer.port, 40002);
    CHECK_EQ(o.receiver, 0x5555u);
    CHECK(memcmp(o.challenge.challenge, first, 16) == 0);

    /* A full period's budget of HELLOs (8): eight CHALLENGEs; the ninth is flood. */
    run_for(PERIOD);
    unsigned sent_before = fb.n_sent;
    uint64_t flood_before = dev.stats.flood;
    for (unsigned i = 0; i < EXO_AUTH_BUDGET + 1u; i++)
        push_hello_from(0x5555u, HOST_IP, 40002);
    exo_device_poll(&dev);
    CHECK_EQ(fb.n_sent - sent_before, EXO_AUTH_BUDGET);
    CHECK_EQ(dev.stats.flood - flood_before, 1);
    CHECK_EQ(dev.stats.challenges, 3 + EXO_AUTH_BUDGET);

    /* 500 ms after it was drawn: still the same; 1 us later: a new one. */
    fb.now = hello_at + 500000;
    push_hello_from(HOST_SESSION, HOST_IP, 40001);
    exo_device_poll(&dev);
    CHECK(last_of_type(&c, EXO_TYPE_CHALLENGE));
    CHECK(memcmp(c.challenge.challenge, first, 16) == 0);
    fb.now = hello_at + 600001;
    push_hello_from(HOST_SESSION, HOST_IP, 40001);
    exo_device_poll(&dev);
    CHECK(last_of_type(&c, EXO_TYPE_CHALLENGE));
    CHECK(memcmp(c.challenge.challenge, first, 16) != 0);
    /* The old one is dead at once, though it would be under 1000 ms old. */
    push_join_full(HOST_SESSION, dev.session, ++host_seq, first, HOST_IP, 40001);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.replayed, 1);
    CHECK_EQ(dev.stats.joins, 0);
    CHECK_EQ(dev.streaming, 0);

    /* No entropy for a challenge: the HELLO goes unanswered, counted. */
    fb.now += 600000;
    fb.random_fail = 1;
    unsigned sent = fb.n_sent;
    push_hello_from(HOST_SESSION, HOST_IP, 40001);
    exo_device_poll(&dev);
    CHECK_EQ(fb.n_sent, sent);
    CHECK_EQ(dev.stats.random_errors, 1);
    fb.random_fail = 0;

    /* The stream is untouched by HELLOs once joined: joined, locked, then HELLOs from
     * the host's and other sessions, with an older host_seq, from other ports. */
    fb.now += 100000;
    CHECK(join(HOST_SESSION, HOST_PORT));
    push_command(EXO_LOCK_LEFT);
    run_for(PERIOD);
    CHECK(fb.left == 1);
    uint32_t applied_seq = dev.host.last_host_seq;
    uint32_t saved = host_seq;
    host_seq = 2; /* a delayed HELLO: older than the applied command */
    push_hello_from(HOST_SESSION, HOST_IP, 40009);
    push_hello_from(0x7777u, HOST_IP, 40010);
    host_seq = saved;
    run_for(PERIOD);
    CHECK_EQ(dev.host.session, HOST_SESSION);
    CHECK_EQ(dev.host.last_host_seq, applied_seq);
    CHECK_EQ(dev.stats.host.port, HOST_PORT);
    exo_packet p;
    CHECK(last_sample(&p));
    CHECK_EQ(fake_last_sent(&fb)->peer.port, HOST_PORT);
    CHECK_EQ(p.receiver, HOST_SESSION);
    CHECK(fb.left == 1); /* no release, no lock change */
    /* ...and an older command is still refused after the delayed HELLO */
    push_command_full(HOST_SESSION, dev.session, applied_seq - 1, last_seq(),
                      EXO_LOCK_LEFT | EXO_LOCK_RIGHT, 0, HOST_IP, HOST_PORT);
    run_for(1000);
    CHECK_EQ(dev.locks, EXO_LOCK_LEFT);
}

/* The JOIN rules, the stream it starts, and what a re-join resets. */
static void join_rules(void)
{
    setup(1, 0);
    CHECK_EQ(start(), 0);
    uint8_t zeros[16];
    memset(zeros, 0, sizeof zeros);

    /* A JOIN with no challenge out (all zeros, as the never-drawn one): replay. */
    push_join_full(HOST_SESSION, dev.session, 1, zeros, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.replayed, 1);

    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    exo_packet c;
    CHECK(last_of_type(&c, EXO_TYPE_CHALLENGE));
    const uint64_t drawn = fb.now;
    uint8_t wrong[16];
    memcpy(wrong, c.challenge.challenge, 16);
    wrong[15] ^= 1;

    /* Addressed to another boot; another challenge: replay, nothing changes. */
    push_join_full(HOST_SESSION, dev.session ^ 1u, ++host_seq, c.challenge.challenge, HOST_IP, HOST_PORT);
    push_join_full(HOST_SESSION, dev.session, ++host_seq, wrong, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.replayed, 3);
    CHECK_EQ(dev.streaming, 0);
    CHECK_EQ(dev.challenge.spent, 0);

    /* The right answer, from port 40100 at 1000 ms: accepted; stream starts at once. */
    fb.now = drawn + 1000000;
    push_join_full(HOST_SESSION, dev.session, 100, c.challenge.challenge, HOST_IP, 40100);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.joins, 1);
    CHECK_EQ(dev.stats.host_known, 1);
    CHECK_EQ(dev.stats.host.port, 40100);
    CHECK_EQ(dev.host.last_host_seq, 100);
    exo_packet p;
    CHECK(last_sample(&p));
    CHECK_EQ(fake_last_sent(&fb)->peer.port, 40100);
    CHECK_EQ(p.sender, dev.session);
    CHECK_EQ(p.receiver, HOST_SESSION);
    CHECK_EQ(p.sample.seq, 0);
    CHECK_EQ(p.sample.t_us, 0);
    CHECK_EQ(p.sample.status & EXO_STATUS_WATCHDOG_RELEASED, EXO_STATUS_WATCHDOG_RELEASED);
    CHECK_EQ(p.sample.replay_drops, 3);

    /* The same JOIN again (a replay), even from the same place: spent. */
    push_join_full(HOST_SESSION, dev.session, 100, c.challenge.challenge, HOST_IP, 40100);
    push_join_full(HOST_SESSION, dev.session, 101, c.challenge.challenge, HOST_IP, 40666);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.replayed, 5);
    CHECK_EQ(dev.stats.joins, 1);
    CHECK_EQ(dev.stats.host.port, 40100);

    /* Expired: a challenge answered 1000.001 ms after it was drawn. */
    fb.now += 600000; /* older than 500 ms: the next HELLO redraws */
    push_hello_from(HOST_SESSION, HOST_IP, 40100);
    exo_device_poll(&dev);
    CHECK(last_of_type(&c, EXO_TYPE_CHALLENGE));
    fb.now += 1000001;
    push_join_full(HOST_SESSION, dev.session, ++host_seq, c.challenge.challenge, HOST_IP, 40100);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.replayed, 6);
    CHECK_EQ(dev.stats.joins, 1);

    /* Locked, then a re-join by the same host session: released, the ring cleared
     * (a command echoing a sample from before the JOIN is stale), the stream goes on
     * (no restart of seq), host_seq restarts from the JOIN's. */
    host_seq = 200;
    push_command_full(HOST_SESSION, dev.session, ++host_seq, last_seq(), EXO_LOCK_LEFT, 1, HOST_IP, 40100);
    run_for(PERIOD);
    CHECK_EQ(dev.stats.commands, 1);
    CHECK(fb.left == 1);
    CHECK_EQ(dev.stop_heartbeat, 1);
    uint32_t before_join = last_seq();
    host_seq = 5; /* a lower host_seq: a JOIN may set it anywhere */
    CHECK(join(HOST_SESSION, 40200));
    CHECK_EQ(dev.host.last_host_seq, host_seq);
    CHECK_EQ(dev.stats.host_changes, 1);
    CHECK_EQ(dev.locks, 0);
    CHECK_EQ(dev.stop_heartbeat, 0);
    push_command_full(HOST_SESSION, dev.session, ++host_seq, before_join, EXO_LOCK_LEFT, 0, HOST_IP, 40200);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.stale_echo, 1);
    run_for(PERIOD);
    CHECK(fb.left == 0);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.seq, before_join + 1); /* the stream went on */
    CHECK_EQ(p.sample.status & (EXO_STATUS_WATCHDOG_RELEASED | EXO_STATUS_SOLENOID_LEFT),
             EXO_STATUS_WATCHDOG_RELEASED);
    CHECK_EQ(p.sample.stale_drops, 1);
    CHECK_EQ(fake_last_sent(&fb)->peer.port, 40200);
    CHECK_EQ(dev.stats.watchdog_releases, 1);

    /* Another host session joins: the first one's commands are replays now. */
    const uint64_t other = 0x1111222233334444u;
    uint32_t old_seq = host_seq;
    CHECK(join(other, 40300));
    push_command_full(HOST_SESSION, dev.session, old_seq + 50, last_seq(), EXO_LOCK_LEFT, 0, HOST_IP, 40200);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.replayed, 7);
    run_for(PERIOD); /* a sample of the new session to answer */
    push_command_full(other, dev.session, ++host_seq, last_seq(), EXO_LOCK_RIGHT, 0, HOST_IP, 40300);
    run_for(PERIOD);
    CHECK(fb.right == 1 && fb.left == 0);
    CHECK(last_sample(&p));
    CHECK_EQ(p.receiver, other);
}

/* COMMAND: replay (boot, session, host_seq), stale_echo (older than 100 ms, unknown),
 * applied (locks, round trip), the watchdog after the last one. */
static void commands_and_watchdog(void)
{
    setup(1, 0);
    CHECK_EQ(start(), 0);
    CHECK(join(HOST_SESSION, HOST_PORT));
    const uint64_t sent0 = fake_last_sent(&fb)->at_us;

    /* A command locking the left side, echoing sample 0 700 us after it. */
    fb.now += 700;
    push_command(EXO_LOCK_LEFT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.commands, 1);
    CHECK_EQ(dev.stats.rtt_n, 1);
    CHECK_EQ(dev.stats.rtt_us[0], fb.now - sent0);
    CHECK_EQ(dev.stats.rtt_us[0], 700);
    CHECK_EQ(fb.energise_calls, 0); /* applied from the next sample period on */
    run_for(PERIOD);
    exo_packet p;
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.status, EXO_STATUS_SOLENOID_LEFT);
    CHECK(fb.left == 1 && fb.right == 0);

    /* Two commands answering the same sample: both applied, each a round trip (as
     * the reference device counts them). */
    push_command(EXO_LOCK_LEFT);
    push_command(EXO_LOCK_LEFT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.commands, 3);
    CHECK_EQ(dev.stats.rtt_n, 3);

    /* Not later than the last applied host_seq (reordered, or a copy): replay. */
    uint32_t applied = host_seq;
    push_command_full(HOST_SESSION, dev.session, applied - 1, last_seq(), EXO_LOCK_RIGHT, 0, HOST_IP, HOST_PORT);
    push_command_full(HOST_SESSION, dev.session, applied, last_seq(), EXO_LOCK_RIGHT, 0, HOST_IP, HOST_PORT);
    push_command_full(HOST_SESSION, dev.session, applied + 0x80000000u, last_seq(), EXO_LOCK_RIGHT, 0,
                      HOST_IP, HOST_PORT); /* exactly half the circle away: earlier */
    /* Addressed to an earlier boot of this device; from another host session. */
    push_command_full(HOST_SESSION, dev.session ^ 1u, applied + 1, last_seq(), EXO_LOCK_RIGHT, 0,
                      HOST_IP, HOST_PORT);
    push_command_full(HOST_SESSION ^ 1u, dev.session, applied + 1, last_seq(), EXO_LOCK_RIGHT, 0,
                      HOST_IP, HOST_PORT);
    /* From another IP, though authentic and fresh. */
    push_command_full(HOST_SESSION, dev.session, applied + 1, last_seq(), EXO_LOCK_RIGHT, 0, OTHER_IP,
                      HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.replayed, 5);
    CHECK_EQ(dev.stats.foreign, 1);
    CHECK_EQ(dev.stats.commands, 3);
    CHECK_EQ(dev.locks, EXO_LOCK_LEFT);
    CHECK_EQ(dev.host.last_host_seq, applied);
    run_for(PERIOD);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.replay_drops, 5); /* the host sees what the device refused */
    CHECK(fb.right == 0);

    /* stale_echo: a sample never sent, one 16 samples back (overwritten), and a lock
     * held back so that its sample is 100.001 ms old; none advances host_seq. */
    push_command_full(HOST_SESSION, dev.session, ++host_seq, last_seq() + 1, EXO_LOCK_RIGHT, 0, HOST_IP,
                      HOST_PORT);
    push_command_full(HOST_SESSION, dev.session, ++host_seq, last_seq() - 16, EXO_LOCK_RIGHT, 0, HOST_IP,
                      HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.stale_echo, 2);
    uint32_t held_echo = last_seq();
    uint64_t held_sent = fake_last_sent(&fb)->at_us;
    uint32_t held_seq = ++host_seq;
    /* Keep the watchdog fed meanwhile with commands numbered below the held one's?
     * No: those would make it a replay. Feed nothing; deliver it late. */
    while (fb.now < held_sent + EXO_FRESH_US)
        run_for(1000);
    CHECK_EQ(fb.now, held_sent + EXO_FRESH_US);
    fb.now += 1;
    push_command_full(HOST_SESSION, dev.session, held_seq, held_echo, EXO_LOCK_RIGHT, 0, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.stale_echo, 3);
    CHECK_EQ(dev.host.last_host_seq, applied); /* not advanced by a stale command */
    CHECK(fb.right == 0);
    /* At exactly 100 ms it is fresh. */
    uint32_t echo = last_seq();
    uint64_t sent_at = fake_last_sent(&fb)->at_us;
    while (fb.now + 1000 <= sent_at + EXO_FRESH_US)
        run_for(1000);
    exo_device_poll(&dev);
    /* (the clock may have passed newer samples; echo the remembered one) */
    fb.now = sent_at + EXO_FRESH_US > fb.now ? sent_at + EXO_FRESH_US : fb.now;
    push_command_full(HOST_SESSION, dev.session, ++host_seq, echo, EXO_LOCK_LEFT | EXO_LOCK_RIGHT, 0,
                      HOST_IP, HOST_PORT);
    uint64_t before = dev.stats.commands;
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.commands, before + (fb.now - sent_at <= EXO_FRESH_US ? 1u : 0u));
    CHECK(fb.now - sent_at == EXO_FRESH_US);

    /* Watchdog: no command after this one. HELLOs keep coming; they do not feed it.
     * The release counts from the time of the sample the command echoes. */
    push_command(EXO_LOCK_LEFT | EXO_LOCK_RIGHT);
    const uint64_t echoed_at = last_sample_at();
    exo_device_poll(&dev);
    uint64_t released_at = 0;
    unsigned released_samples = 0;
    for (unsigned ms = 1; ms <= 200; ms++) {
        fb.now += 1000;
        if (ms % 20 == 0)
            push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
        unsigned n_before = fb.n_sent;
        exo_device_poll(&dev);
        if (fb.n_sent != n_before && last_sample(&p)
            && (p.sample.status & EXO_STATUS_WATCHDOG_RELEASED)) {
            if (!released_at)
                released_at = fb.now;
            released_samples++;
            CHECK_EQ(p.sample.status & (EXO_STATUS_SOLENOID_LEFT | EXO_STATUS_SOLENOID_RIGHT), 0);
        }
        if (!released_at && ms >= PERIOD / 1000) /* applied from the next period on */
            CHECK(fb.left == 1 && fb.right == 1);
    }
    CHECK(released_at > echoed_at + EXO_WATCHDOG_US);
    CHECK(released_at <= echoed_at + EXO_WATCHDOG_US + PERIOD);
    CHECK(fb.left == 0 && fb.right == 0);
    CHECK(released_samples >= 9);

    /* A new command energises again; stop releases at once and for good. */
    push_command(EXO_LOCK_RIGHT);
    run_for(PERIOD);
    CHECK(fb.right == 1);
    exo_device_stop(&dev);
    CHECK(fb.left == 0 && fb.right == 0);
    unsigned sent = fb.n_sent, energised = fb.energise_calls;
    push_command(EXO_LOCK_RIGHT);
    run_for(5 * PERIOD);
    CHECK_EQ(fb.n_sent, sent);
    CHECK_EQ(fb.energise_calls, energised);
    CHECK(fb.right == 0);
    /* stop wiped the absorbed key */
    uint8_t zero_key[sizeof dev.key];
    memset(zero_key, 0, sizeof zero_key);
    CHECK(memcmp(&dev.key, zero_key, sizeof zero_key) == 0);
}

/* Whatever the phase of the last command within the sample period, the release comes
 * 100-110 ms after the sample it echoes was sent; it does not wait for 100 ms after
 * the command's arrival. */
static void watchdog_phases(void)
{
    for (unsigned phase = 0; phase < PERIOD; phase += 1250) {
        setup(0, 0);
        CHECK_EQ(start(), 0);
        CHECK(join(HOST_SESSION, HOST_PORT));
        const uint64_t echoed_at = last_sample_at();
        fb.now += phase;
        push_command(EXO_LOCK_LEFT);
        exo_device_poll(&dev);
        uint64_t off_at = 0;
        for (unsigned step = 0; step < 400 && !off_at; step++) {
            int was_on = fb.left;
            fb.now += 500;
            exo_device_poll(&dev);
            if (was_on && !fb.left)
                off_at = fb.now;
        }
        CHECK(off_at > echoed_at + EXO_WATCHDOG_US);
        CHECK(off_at <= echoed_at + EXO_WATCHDOG_US + PERIOD);
    }
}

/* A lock command held back on the path (up to the 100 ms freshness limit) and no
 * command after it: the outputs it drives drop within 100 ms + one period of the
 * echoed sample's send time, so the delay shortens the lock and never extends it. */
static void delayed_command_watchdog(void)
{
    static const unsigned delays_ms[] = {0, 5, 50, 89, 95, 99, 100};
    for (unsigned i = 0; i < sizeof delays_ms / sizeof delays_ms[0]; i++) {
        setup(0, 0);
        CHECK_EQ(start(), 0);
        CHECK(join(HOST_SESSION, HOST_PORT));
        uint32_t echo = last_seq();
        const uint64_t echoed_at = last_sample_at();
        run_for((uint64_t)delays_ms[i] * 1000u); /* samples go on; no command arrives */
        push_command_full(HOST_SESSION, dev.session, ++host_seq, echo, EXO_LOCK_LEFT, 0,
                          HOST_IP, HOST_PORT);
        exo_device_poll(&dev);
        CHECK_EQ(dev.stats.commands, 1); /* fresh: applied */
        uint64_t last_on = 0;
        unsigned on_samples = 0;
        for (unsigned step = 0; step < 300; step++) {
            fb.now += 1000;
            unsigned n_before = fb.n_sent;
            exo_device_poll(&dev);
            exo_packet p;
            if (fb.n_sent != n_before && last_sample(&p)
                && (p.sample.status & EXO_STATUS_SOLENOID_LEFT)) {
                last_on = fb.now;
                on_samples++;
            }
        }
        CHECK(fb.left == 0);
        CHECK_EQ(dev.stats.watchdog_releases, on_samples ? 1u : 0u);
        CHECK(last_on <= echoed_at + EXO_WATCHDOG_US);
        /* Applied from the next period on, while the echoed sample is recent enough. */
        if (delays_ms[i] + PERIOD / 1000u < EXO_WATCHDOG_US / 1000u)
            CHECK(on_samples >= (EXO_WATCHDOG_US / 1000u - delays_ms[i]) / (PERIOD / 1000u) - 1u);
    }
}

/* Source first, then at most 8 datagrams from the host IP per period reach
 * validation (and so the tag check); the rest are unread (flood). Every datagram is
 * counted once, empty ones included. */
static void flood_budget(void)
{
    setup(1, 0);
    CHECK_EQ(start(), 0);
    uint8_t d[EXO_MAX_PACKET];
    size_t n = exo_wire_encode_hello(&key, 1, HOST_SESSION, 0, d, sizeof d);
    d[n - 1] ^= 1; /* forged */
    /* Idle period: 3 empty, 20 forged, 4 empty from another IP, 1 authentic HELLO,
     * 1 more empty. */
    for (unsigned i = 0; i < 3; i++)
        fake_push(&fb, d, 0, HOST_IP, HOST_PORT);
    for (unsigned i = 0; i < 20; i++)
        fake_push(&fb, d, (long)n, HOST_IP, HOST_PORT);
    for (unsigned i = 0; i < 4; i++)
        fake_push(&fb, d, 0, OTHER_IP, HOST_PORT);
    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    fake_push(&fb, d, 0, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.malformed[EXO_DROP_SHORT], 3); /* read and counted */
    CHECK_EQ(dev.stats.malformed[EXO_DROP_AUTH], 5);  /* the budget's other 5 */
    CHECK_EQ(dev.stats.flood, 17); /* 15 forged, the authentic HELLO, the empty one */
    CHECK_EQ(dev.stats.foreign, 4);
    CHECK_EQ(dev.stats.hellos, 0);
    CHECK_EQ(fb.n_sent, 0);
    /* The next period has a new budget: the HELLO gets through. */
    run_for(PERIOD);
    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.hellos, 1);
    CHECK_EQ(dev.stats.challenges, 1);

    /* Streaming: per sample period; the host's own command after 8 forgeries is
     * dropped (an attacker can stop the link, never lock). */
    CHECK(join(HOST_SESSION, HOST_PORT));
    run_for(PERIOD);
    uint64_t auth = dev.stats.malformed[EXO_DROP_AUTH], flood = dev.stats.flood;
    for (unsigned i = 0; i < 10; i++)
        fake_push(&fb, d, (long)n, HOST_IP, HOST_PORT);
    push_command(EXO_LOCK_LEFT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.malformed[EXO_DROP_AUTH] - auth, 8);
    CHECK_EQ(dev.stats.flood - flood, 3);
    CHECK_EQ(dev.stats.commands, 0);
    run_for(PERIOD);
    push_command(EXO_LOCK_LEFT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.commands, 1);
    /* Oversize datagrams and failed receives: the former count as length and take
     * budget, the latter (no datagram) neither. */
    unsigned checks = dev.auth_checks;
    uint8_t big[300];
    memset(big, 'E', sizeof big);
    fake_push(&fb, big, 300, HOST_IP, HOST_PORT);
    fb.receive_error_once = 1;
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.malformed[EXO_DROP_LENGTH], 1);
    CHECK_EQ(dev.stats.receive_errors, 1);
    CHECK_EQ(dev.auth_checks, checks + 1);
}

/* Packets only a device sends, and another protocol version (answered by VERSION,
 * at most once per second). */
static void unexpected_and_version(void)
{
    setup(0, 0);
    CHECK_EQ(start(), 0);
    uint8_t d[EXO_MAX_PACKET];
    exo_sample_fields s;
    memset(&s, 0, sizeof s);
    size_t n = exo_wire_encode_sample(&key, &s, HOST_SESSION, dev.session, d, sizeof d);
    fake_push(&fb, d, (long)n, HOST_IP, HOST_PORT);
    n = exo_wire_encode_version(&key, 3, 3, d, sizeof d);
    fake_push(&fb, d, (long)n, HOST_IP, HOST_PORT);
    exo_challenge_fields cf;
    memset(&cf, 0, sizeof cf);
    cf.firmware[0] = 'h';
    n = exo_wire_encode_challenge(&key, &cf, HOST_SESSION, dev.session, d, sizeof d);
    fake_push(&fb, d, (long)n, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.unexpected, 3);
    CHECK_EQ(fb.n_sent, 0);

    /* A version 2 HELLO (authentic: same key) from the host: dropped as `version`,
     * answered with VERSION 3..3 to its source. */
    n = exo_wire_encode_hello(&key, 1, HOST_SESSION, 0, d, sizeof d);
    d[2] = 2;
    exo_hmac_sha256(&key, d, n - EXO_TAG_BYTES, NULL, 0, d + n - EXO_TAG_BYTES);
    fake_push(&fb, d, (long)n, HOST_IP, 41000);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.malformed[EXO_DROP_VERSION], 1);
    CHECK_EQ(dev.stats.versions_sent, 1);
    CHECK_EQ(fb.n_sent, 1);
    exo_packet v;
    CHECK(last_of_type(&v, EXO_TYPE_VERSION));
    CHECK_EQ(v.lowest, 3);
    CHECK_EQ(v.highest, 3);
    CHECK_EQ(fake_last_sent(&fb)->peer.port, 41000);
    CHECK_EQ(fake_last_sent(&fb)->len, 44);
    /* Again 999 ms later: counted, not answered; at 1000 ms: answered. */
    uint64_t first = fb.now;
    fb.now = first + 999999;
    fake_push(&fb, d, (long)n, HOST_IP, 41000);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.malformed[EXO_DROP_VERSION], 2);
    CHECK_EQ(dev.stats.versions_sent, 1);
    fb.now = first + 1000000;
    fake_push(&fb, d, (long)n, HOST_IP, 41000);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.versions_sent, 2);
    /* Not authentic, or not from the host: never answered. */
    fb.now += 2000000;
    d[n - 1] ^= 1;
    fake_push(&fb, d, (long)n, HOST_IP, 41000);
    d[n - 1] ^= 1;
    fake_push(&fb, d, (long)n, OTHER_IP, 41000);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.versions_sent, 2);
    CHECK_EQ(dev.stats.malformed[EXO_DROP_AUTH], 1);
    CHECK_EQ(dev.stats.foreign, 1);
    CHECK_EQ(dev.streaming, 0);
}

/* The heartbeat: one edge per sample period; STOP_HEARTBEAT stops it (and says so)
 * while the latest applied command carries it; it resumes with a command without it
 * or when the watchdog releases. DRIVERS_OFF comes from the board. */
static void heartbeat(void)
{
    setup(1, 0);
    CHECK_EQ(start(), 0);
    CHECK(join(HOST_SESSION, HOST_PORT));
    unsigned edges = fb.heartbeat_edges;
    run_for(5 * PERIOD);
    CHECK_EQ(fb.heartbeat_edges - edges, 5);

    push_command_full(HOST_SESSION, dev.session, ++host_seq, last_seq(), EXO_LOCK_LEFT, 1, HOST_IP,
                      HOST_PORT);
    exo_device_poll(&dev);
    edges = fb.heartbeat_edges;
    fb.status = EXO_STATUS_DRIVERS_OFF; /* the monostable dropped the enable */
    exo_packet p;
    for (unsigned i = 0; i < 5; i++) {
        run_for(PERIOD);
        push_command_full(HOST_SESSION, dev.session, ++host_seq, last_seq(), EXO_LOCK_LEFT, 1,
                          HOST_IP, HOST_PORT);
        exo_device_poll(&dev);
    }
    CHECK_EQ(fb.heartbeat_edges, edges);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.status, EXO_STATUS_SOLENOID_LEFT | EXO_STATUS_HEARTBEAT_STOPPED
                                  | EXO_STATUS_DRIVERS_OFF);
    /* A command without the flag: the heartbeat resumes at the next period. */
    fb.status = 0;
    push_command(EXO_LOCK_LEFT);
    run_for(PERIOD);
    CHECK_EQ(fb.heartbeat_edges, edges + 1);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.status, EXO_STATUS_SOLENOID_LEFT);
    /* Stopped again, then no more commands: the watchdog releases and the heartbeat
     * resumes in the same period. */
    push_command_full(HOST_SESSION, dev.session, ++host_seq, last_seq(), 0, 1, HOST_IP, HOST_PORT);
    run_for(PERIOD);
    edges = fb.heartbeat_edges;
    run_for(EXO_WATCHDOG_US + 2 * PERIOD);
    CHECK(fb.heartbeat_edges > edges);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.status, EXO_STATUS_WATCHDOG_RELEASED);
    CHECK_EQ(dev.stop_heartbeat, 0);
    /* A board without the pin: nothing is called, the status still says so. */
    setup(0, 0);
    CHECK_EQ(start(), 0);
    CHECK(join(HOST_SESSION, HOST_PORT));
    push_command_full(HOST_SESSION, dev.session, ++host_seq, last_seq(), 0, 1, HOST_IP, HOST_PORT);
    run_for(PERIOD);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.status, EXO_STATUS_HEARTBEAT_STOPPED);
    CHECK_EQ(fb.heartbeat_edges, 0);
}

/* host_seq and sample seq across 0xFFFFFFFF -> 0, on a clock past 2^32 us (the
 * 71-minute wrap of a 32-bit microsecond timer must not exist in the core). */
static void wraps(void)
{
    setup(0, 0);
    fb.now = 0xFFFFFFFFull - 25000u; /* 25 ms before 2^32 us */
    CHECK_EQ(start(), 0);
    host_seq = 0xFFFFFFFDu;
    CHECK(join(HOST_SESSION, HOST_PORT)); /* HELLO 0xFFFFFFFE, JOIN 0xFFFFFFFF */
    CHECK_EQ(dev.host.last_host_seq, 0xFFFFFFFFu);
    /* Sample seq about to wrap. */
    dev.k = 0xFFFFFFFEu;
    dev.start_us = fb.now - (uint64_t)0xFFFFFFFEu * PERIOD;
    exo_packet p;
    for (unsigned i = 0; i < 4; i++) {
        exo_device_poll(&dev);
        CHECK(last_sample(&p));
        CHECK_EQ(p.sample.seq, (uint32_t)(0xFFFFFFFEu + i));
        /* The command answering it, host_seq 0, 1, 2, 3 after 0xFFFFFFFF. */
        push_command(i % 2 ? EXO_LOCK_RIGHT : EXO_LOCK_LEFT);
        fb.now += 1000;
        exo_device_poll(&dev);
        CHECK_EQ(dev.stats.commands, i + 1);
        CHECK_EQ(dev.host.last_host_seq, i);
        fb.now += PERIOD - 1000;
    }
    CHECK(fb.now > 0x100000000ull);
    CHECK_EQ(p.sample.t_us, (uint64_t)0x100000001ull * PERIOD);
    /* The command numbered 0xFFFFFFFF (before the wrap) is now a replay. */
    push_command_full(HOST_SESSION, dev.session, 0xFFFFFFFFu, last_seq(), EXO_LOCK_LEFT, 0, HOST_IP,
                      HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.replayed, 1);
    /* The watchdog and the challenge lifetime work across 2^32 us as anywhere. */
    run_for(EXO_WATCHDOG_US + 2 * PERIOD);
    CHECK(last_sample(&p));
    CHECK(p.sample.status & EXO_STATUS_WATCHDOG_RELEASED);
    CHECK_EQ(dev.stats.watchdog_releases, 1);
    CHECK_EQ(dev.stats.late, 0);
}

static void timing(void)
{
    setup(0, 0);
    CHECK_EQ(start(), 0);
    CHECK(join(HOST_SESSION, HOST_PORT));

    /* A slow send (3 ms): the sample is late. */
    fb.send_delay_us = 3000;
    run_for(PERIOD);
    CHECK_EQ(dev.stats.late, 1);
    CHECK_EQ(dev.stats.lateness_max_us, 3000);
    CHECK_EQ(dev.stats.lateness_n, 2);
    CHECK_EQ(dev.stats.lateness_us[1], 3000);
    fb.send_delay_us = 0;

    /* Behind by 50 ms (< 250 ms): catch up sample by sample, no rebase. */
    unsigned before = fb.n_sent;
    fb.now += 50000;
    unsigned polls = 0;
    while (exo_device_poll(&dev) == 0 && polls < 20)
        polls++;
    CHECK_EQ(dev.stats.resyncs, 0);
    CHECK(fb.n_sent - before >= 5);
    CHECK(dev.stats.late >= 5);

    /* A 300 ms stall: one rebase, no burst, the sequence and device time go on. */
    exo_packet p;
    CHECK(last_sample(&p));
    uint32_t seq = p.sample.seq;
    fb.now += 300000;
    before = fb.n_sent;
    CHECK(exo_device_poll(&dev) > 0);
    CHECK_EQ(dev.stats.resyncs, 1);
    CHECK_EQ(fb.n_sent - before, 1);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.seq, seq + 1);
    CHECK_EQ(p.sample.t_us, (uint64_t)(seq + 1) * PERIOD);

    /* The sequence wraps 2^32 - 1 -> 0. */
    dev.k = 0xFFFFFFFFu;
    dev.start_us = fb.now - (uint64_t)0xFFFFFFFFu * PERIOD;
    exo_device_poll(&dev);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.seq, 0xFFFFFFFFu);
    fb.now += PERIOD;
    exo_device_poll(&dev);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.seq, 0);
    CHECK_EQ(p.sample.t_us, (uint64_t)0x100000000u * PERIOD);

    /* A send that fails is counted (and the sample still counted as built). */
    uint64_t built = dev.stats.samples_sent;
    fb.send_fail = 1;
    fb.now += PERIOD;
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.send_errors, 1);
    CHECK_EQ(dev.stats.samples_sent, built + 1);
    fb.send_fail = 0;
}

static void rate_factor(void)
{
    setup(0, 0);
    cfg.rate_factor = 2;
    CHECK_EQ(start(), 0);
    CHECK(join(HOST_SESSION, HOST_PORT));
    unsigned sent = fb.n_sent;
    CHECK_EQ(exo_device_poll(&dev), PERIOD / 2);
    run_for(PERIOD);
    exo_packet p;
    CHECK_EQ(fb.n_sent - sent, 2);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.seq, 2);
    CHECK_EQ(p.sample.t_us, PERIOD); /* honest device time: two samples per period */
}

static void board_status_truth_and_encoders(void)
{
    setup(1, 1); /* daisy chain */
    fb.status = 0xFFFFFFFFu; /* a board reporting garbage in every bit */
    fb.truth_on = 1;
    fb.truth.progress = 0.25;
    fb.truth.lift_index = 7;
    fb.truth.activity_len = 4;
    memcpy(fb.truth.activity, "walk", 4);
    CHECK_EQ(start(), 0);
    CHECK(join(HOST_SESSION, HOST_PORT));
    exo_packet p;
    CHECK(last_sample(&p)); /* still a valid packet */
    CHECK_EQ(p.sample.status, EXO_STATUS_LOCKED_LEFT | EXO_STATUS_LOCKED_RIGHT
                                  | EXO_STATUS_HARD_STOP_LEFT | EXO_STATUS_HARD_STOP_RIGHT
                                  | EXO_STATUS_ENCODER_FAULT | EXO_STATUS_SUPPLY_FAULT
                                  | EXO_STATUS_DRIVERS_OFF | EXO_STATUS_WATCHDOG_RELEASED);
    CHECK_EQ(p.sample.has_truth, 1);
    CHECK(p.sample.truth.progress == 0.25);
    CHECK_EQ(p.sample.truth.lift_index, 7);
    CHECK(memcmp(p.sample.truth.activity, "walk", 4) == 0);
    CHECK_EQ(fb.spi_wrong_shape, 0);
    CHECK_EQ(fb.spi_calls, 3); /* three 4-frame transfers on chip 0 */
    CHECK_EQ(p.sample.status & EXO_STATUS_HEARTBEAT_STOPPED, 0); /* the core's own bit */

    /* An encoder fault is reported, the packet stays valid, counts masked. */
    fb.status = 0;
    fb.enc[2].corrupt_angle = 1;
    run_for(PERIOD);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.status, EXO_STATUS_ENCODER_FAULT | EXO_STATUS_WATCHDOG_RELEASED);
    fb.enc[2].corrupt_angle = 0;
    run_for(2 * PERIOD); /* cleared, then clean */
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.status, EXO_STATUS_WATCHDOG_RELEASED);
    CHECK_EQ(p.sample.counts[2], fb.enc[2].angle);

    /* A truth the wire cannot carry (65-byte name) is a send error, as in the
     * reference device; the sample is not sent. */
    unsigned sent = fb.n_sent;
    fb.truth.activity_len = 65;
    run_for(PERIOD);
    CHECK_EQ(fb.n_sent, sent);
    CHECK_EQ(dev.stats.send_errors, 1);
    CHECK_EQ(fb.frames_bad_parity, 0);
}

void test_device(void)
{
    startup();
    hello_and_challenge();
    join_rules();
    commands_and_watchdog();
    watchdog_phases();
    delayed_command_watchdog();
    flood_budget();
    unexpected_and_version();
    heartbeat();
    wraps();
    timing();
    rate_factor();
    board_status_truth_and_encoders();
}
