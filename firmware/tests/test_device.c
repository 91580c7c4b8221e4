/*
 * test_device.c - the device loop against the fake board: start-up (solenoids
 * released, entropy required), learning the host from an authentic HELLO or COMMAND
 * from the configured IP only, the sample stream and its schedule, commands (stale,
 * replayed, addressed to an earlier boot, forged), the watchdog release 100-110 ms
 * after the last command, round trips, late samples and resyncs, the drop counts in
 * the samples, the rate-factor probe, ground truth, and stop.
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

static void push_command_full(uint64_t session, uint64_t to, uint32_t seq, unsigned locks,
                              int echo_valid, uint32_t echo, uint32_t ip, uint16_t port)
{
    uint8_t d[EXO_MAX_PACKET];
    size_t n = exo_wire_encode_command(&key, seq, echo_valid, echo, locks, session, to, d, sizeof d);
    fake_push(&fb, d, (long)n, ip, port);
}

static void push_command(unsigned locks)
{
    push_command_full(HOST_SESSION, dev.session, ++host_seq, locks, 0, 0, HOST_IP, HOST_PORT);
}

/* Decode the latest sample the device sent; 0 if there is none or it is invalid. */
static int last_sample(exo_packet *p)
{
    const fake_datagram *d = fake_last_sent(&fb);
    if (!d)
        return 0;
    return exo_wire_decode(&key, d->data, (size_t)d->len, p) == EXO_DROP_NONE
           && p->type == EXO_TYPE_SAMPLE;
}

/* Move the clock by `us` in 1 ms steps, polling at each (a port polling often). */
static void run_for(uint64_t us)
{
    for (uint64_t t = 0; t < us; t += 1000) {
        fb.now += 1000;
        exo_device_poll(&dev);
    }
}

static void startup(void)
{
    setup(1, 0);
    fb.left = fb.right = 1; /* as if the pins came up energised */
    CHECK_EQ(start(), 0);
    CHECK_EQ(fb.solenoid_calls, 1); /* released first thing */
    CHECK(fb.left == 0 && fb.right == 0);
    CHECK(dev.session != 0);
    CHECK_EQ(dev.session, 0xA7A6A5A4A3A2A1A0u); /* from the board's random bytes */
    CHECK(dev.watchdog.released == 1);

    /* No host yet: nothing sent, encoders and solenoids untouched, hardware watchdog
     * kicked once per period. */
    uint32_t wait = exo_device_poll(&dev);
    CHECK(wait > 0 && wait <= PERIOD);
    run_for(100000);
    CHECK_EQ(fb.n_sent, 0);
    CHECK_EQ(fb.spi_calls, 0);
    CHECK_EQ(fb.solenoid_calls, 1);
    CHECK(fb.kicks >= 10 && fb.kicks <= 11);

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

    /* A board without a required function, or a rate factor out of range. */
    setup(0, 0);
    board.send = NULL;
    CHECK_EQ(start(), -1);
    setup(0, 0);
    cfg.rate_factor = 101;
    CHECK_EQ(start(), -1);
    cfg.rate_factor = 100;
    CHECK_EQ(start(), 0);
}

static void learn_host_and_stream(void)
{
    setup(1, 0);
    CHECK_EQ(start(), 0);

    /* From another IP: ignored and counted, however authentic. */
    push_hello_from(HOST_SESSION, OTHER_IP, HOST_PORT);
    run_for(20000);
    CHECK_EQ(dev.stats.foreign, 1);
    CHECK_EQ(fb.n_sent, 0);
    CHECK_EQ(dev.stats.host_known, 0);

    /* Forged (wrong tag) from the right IP: counted, not learned. */
    uint8_t d[EXO_MAX_PACKET];
    size_t n = exo_wire_encode_hello(&key, 1, HOST_SESSION, 0, d, sizeof d);
    d[n - 1] ^= 0x80;
    fake_push(&fb, d, (long)n, HOST_IP, HOST_PORT);
    run_for(10000);
    CHECK_EQ(dev.stats.malformed[EXO_DROP_AUTH], 1);
    CHECK_EQ(dev.stats.host_known, 0);
    CHECK_EQ(fb.n_sent, 0);

    /* The HELLO: the host's port is learned and sample 0 goes out at once. */
    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    uint64_t hello_at = fb.now;
    uint32_t wait = exo_device_poll(&dev);
    CHECK_EQ(dev.stats.hellos, 1);
    CHECK_EQ(dev.stats.host_known, 1);
    CHECK_EQ(dev.stats.host.ip, HOST_IP);
    CHECK_EQ(dev.stats.host.port, HOST_PORT);
    CHECK_EQ(fb.n_sent, 1);
    CHECK_EQ(wait, PERIOD);
    exo_packet p;
    CHECK(last_sample(&p));
    CHECK_EQ(fake_last_sent(&fb)->peer.ip, HOST_IP);
    CHECK_EQ(fake_last_sent(&fb)->peer.port, HOST_PORT);
    CHECK_EQ(p.sender, dev.session);
    CHECK_EQ(p.receiver, HOST_SESSION);
    CHECK_EQ(p.sample.seq, 0);
    CHECK_EQ(p.sample.t_us, 0);
    CHECK_EQ(p.sample.status, EXO_STATUS_WATCHDOG_RELEASED); /* no command yet */
    CHECK_EQ(p.sample.auth_drops, 1); /* the forged HELLO */
    CHECK_EQ(p.sample.replay_drops, 0);
    for (unsigned i = 0; i < 4; i++)
        CHECK_EQ(p.sample.counts[i], fb.enc[i].angle);
    CHECK_EQ(p.sample.has_truth, 0);

    /* The hardware watchdog is kicked with every sample while streaming. */
    unsigned kicks = fb.kicks;

    /* The schedule: one sample per 10 ms on the device clock, t_us = k * 10000. */
    fb.now = hello_at + 4000;
    CHECK_EQ(exo_device_poll(&dev), PERIOD - 4000);
    CHECK_EQ(fb.n_sent, 1);
    fb.now = hello_at + PERIOD;
    exo_device_poll(&dev);
    CHECK_EQ(fb.n_sent, 2);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.seq, 1);
    CHECK_EQ(p.sample.t_us, PERIOD);
    run_for(3 * PERIOD);
    CHECK_EQ(fb.n_sent, 5);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.seq, 4);
    CHECK_EQ(p.sample.t_us, 4 * PERIOD);
    CHECK_EQ(dev.stats.samples_sent, 5);
    CHECK_EQ(fb.kicks - kicks, 4);
    CHECK_EQ(dev.stats.late, 0);
    CHECK_EQ(fb.energise_calls, 0);
    CHECK_EQ(fb.spi_wrong_shape, 0);

    /* A SAMPLE sent to the device: valid, but not something a host sends. */
    exo_sample_fields s;
    memset(&s, 0, sizeof s);
    n = exo_wire_encode_sample(&key, &s, HOST_SESSION, dev.session, d, sizeof d);
    fake_push(&fb, d, (long)n, HOST_IP, HOST_PORT);
    /* Oversize datagrams: counted as length (or foreign, by source first). */
    uint8_t big[300];
    memset(big, 'E', sizeof big);
    fake_push(&fb, big, 300, HOST_IP, HOST_PORT);
    fake_push(&fb, big, 300, OTHER_IP, HOST_PORT);
    fb.receive_error_once = 1;
    run_for(1000);
    CHECK_EQ(dev.stats.unexpected, 1);
    CHECK_EQ(dev.stats.malformed[EXO_DROP_LENGTH], 1);
    CHECK_EQ(dev.stats.foreign, 2);
    CHECK_EQ(dev.stats.receive_errors, 1);
}

static void commands_and_watchdog(void)
{
    setup(1, 0);
    CHECK_EQ(start(), 0);
    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    exo_device_poll(&dev); /* sample 0 */
    const uint64_t sent0 = fake_last_sent(&fb)->at_us;

    /* A command locking the left side, echoing sample 0. */
    fb.now += 700;
    push_command_full(HOST_SESSION, dev.session, ++host_seq, EXO_LOCK_LEFT, 1, 0, HOST_IP,
                      HOST_PORT);
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

    /* The same echo again does not count a second round trip. */
    push_command_full(HOST_SESSION, dev.session, ++host_seq, EXO_LOCK_LEFT, 1, 0, HOST_IP,
                      HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.commands, 2);
    CHECK_EQ(dev.stats.rtt_n, 1);

    /* Stale: authentic and unseen, but not after the last applied host_seq (a
     * command overtaken in the network). */
    host_seq += 3;
    push_command_full(HOST_SESSION, dev.session, host_seq, EXO_LOCK_LEFT, 0, 0, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.commands, 3);
    uint32_t applied = host_seq;
    push_command_full(HOST_SESSION, dev.session, applied - 1, EXO_LOCK_RIGHT, 0, 0, HOST_IP,
                      HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.stale_commands, 1);
    CHECK_EQ(dev.locks, EXO_LOCK_LEFT);
    /* Replayed: the very same host_seq again (the window catches it first). */
    push_command_full(HOST_SESSION, dev.session, applied, EXO_LOCK_RIGHT, 0, 0, HOST_IP, HOST_PORT);
    /* Addressed to an earlier boot of this device. */
    push_command_full(HOST_SESSION, dev.session ^ 1u, ++host_seq, EXO_LOCK_RIGHT, 0, 0, HOST_IP,
                      HOST_PORT);
    /* From another IP, though authentic and fresh. */
    push_command_full(HOST_SESSION, dev.session, ++host_seq, EXO_LOCK_RIGHT, 0, 0, OTHER_IP,
                      HOST_PORT);
    exo_device_poll(&dev);
    CHECK_EQ(dev.stats.replayed, 2);
    CHECK_EQ(dev.stats.foreign, 1);
    CHECK_EQ(dev.stats.commands, 3);
    CHECK_EQ(dev.locks, EXO_LOCK_LEFT);
    run_for(PERIOD);
    CHECK(last_sample(&p));
    CHECK_EQ(p.sample.replay_drops, 2); /* the host sees what the device refused */
    CHECK(fb.right == 0);

    /* Watchdog: no command after this one. HELLOs keep coming; they do not feed it. */
    push_command(EXO_LOCK_LEFT | EXO_LOCK_RIGHT);
    exo_device_poll(&dev);
    const uint64_t last_cmd = fb.now;
    uint64_t released_at = 0;
    unsigned released_samples = 0;
    for (unsigned ms = 1; ms <= 200; ms++) {
        fb.now += 1000;
        if (ms % 20 == 0)
            push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
        unsigned before = fb.n_sent;
        exo_device_poll(&dev);
        if (fb.n_sent != before && last_sample(&p)
            && (p.sample.status & EXO_STATUS_WATCHDOG_RELEASED)) {
            if (!released_at)
                released_at = fb.now;
            released_samples++;
            CHECK_EQ(p.sample.status & (EXO_STATUS_SOLENOID_LEFT | EXO_STATUS_SOLENOID_RIGHT), 0);
        }
        if (!released_at && ms >= PERIOD / 1000) /* applied from the next period on */
            CHECK(fb.left == 1 && fb.right == 1);
    }
    CHECK(released_at > last_cmd + EXO_WATCHDOG_US);
    CHECK(released_at <= last_cmd + EXO_WATCHDOG_US + PERIOD);
    CHECK(fb.left == 0 && fb.right == 0);
    CHECK_EQ(dev.stats.watchdog_releases, 1);
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
}

/* Whatever the phase of the last command within the sample period, the release comes
 * 100-110 ms after it. */
static void watchdog_phases(void)
{
    for (unsigned phase = 0; phase < PERIOD; phase += 1250) {
        setup(0, 0);
        CHECK_EQ(start(), 0);
        push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
        exo_device_poll(&dev);
        fb.now += phase;
        push_command(EXO_LOCK_LEFT);
        exo_device_poll(&dev);
        uint64_t last_cmd = fb.now;
        uint64_t off_at = 0;
        for (unsigned step = 0; step < 400 && !off_at; step++) {
            int was_on = fb.left;
            fb.now += 500;
            exo_device_poll(&dev);
            if (was_on && !fb.left)
                off_at = fb.now;
        }
        CHECK(off_at > last_cmd + EXO_WATCHDOG_US);
        CHECK(off_at <= last_cmd + EXO_WATCHDOG_US + PERIOD);
    }
}

static void sessions_and_ports(void)
{
    setup(0, 0);
    CHECK_EQ(start(), 0);
    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    push_command(EXO_LOCK_LEFT);
    run_for(PERIOD);
    CHECK_EQ(dev.stats.commands, 1);

    /* The host restarts: new session, its sequence starts again at 1. */
    const uint64_t new_host = 0x1111222233334444u;
    host_seq = 0;
    push_hello_from(new_host, HOST_IP, HOST_PORT);
    run_for(PERIOD);
    exo_packet p;
    CHECK(last_sample(&p));
    CHECK_EQ(p.receiver, new_host);
    CHECK_EQ(dev.stats.host_changes, 0); /* same port */
    push_command_full(new_host, dev.session, ++host_seq, EXO_LOCK_RIGHT, 0, 0, HOST_IP, HOST_PORT);
    /* The old host session is retired: its fresh-looking command is a replay. */
    push_command_full(HOST_SESSION, dev.session, 1000, EXO_LOCK_LEFT, 0, 0, HOST_IP, HOST_PORT);
    run_for(PERIOD);
    CHECK_EQ(dev.stats.commands, 2);
    CHECK_EQ(dev.stats.replayed, 1);
    CHECK_EQ(dev.locks, EXO_LOCK_RIGHT);

    /* The same host on a new port: samples follow it, counted as a host change. */
    push_command_full(new_host, dev.session, ++host_seq, EXO_LOCK_RIGHT, 0, 0, HOST_IP, 50001);
    run_for(PERIOD);
    CHECK_EQ(dev.stats.host_changes, 1);
    CHECK_EQ(dev.stats.host.port, 50001);
    CHECK_EQ(fake_last_sent(&fb)->peer.port, 50001);
    CHECK_EQ(dev.stats.commands, 3);

    /* A port change also forgets the last applied host_seq (as the reference device
     * does): an unseen, lower number from the new port is applied, not stale; from
     * the same port it would have been stale. */
    uint32_t top = host_seq;
    push_command_full(new_host, dev.session, top - 5, EXO_LOCK_LEFT, 0, 0, HOST_IP, 50001);
    run_for(1000);
    CHECK_EQ(dev.stats.stale_commands, 1);
    push_command_full(new_host, dev.session, top - 6, EXO_LOCK_LEFT, 0, 0, HOST_IP, 50002);
    run_for(1000);
    CHECK_EQ(dev.stats.stale_commands, 1);
    CHECK_EQ(dev.stats.commands, 4);
    CHECK_EQ(dev.stats.host_changes, 2);
    CHECK_EQ(dev.locks, EXO_LOCK_LEFT);
    push_command_full(new_host, dev.session, top + 1, EXO_LOCK_RIGHT, 0, 0, HOST_IP, 50001);
    run_for(1000);
    CHECK_EQ(dev.stats.host_changes, 3);
    CHECK_EQ(dev.stats.commands, 5);

    /* Session 0 is never a sender, even in a HELLO. */
    push_hello_from(0, HOST_IP, HOST_PORT);
    run_for(1000);
    CHECK_EQ(dev.stats.replayed, 2);
    CHECK_EQ(dev.stats.host.port, 50001);
}

static void timing(void)
{
    setup(0, 0);
    CHECK_EQ(start(), 0);
    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);

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
}

static void rate_factor(void)
{
    setup(0, 0);
    cfg.rate_factor = 2;
    CHECK_EQ(start(), 0);
    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    CHECK_EQ(exo_device_poll(&dev), PERIOD / 2);
    run_for(PERIOD);
    exo_packet p;
    CHECK_EQ(fb.n_sent, 3);
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
    push_hello_from(HOST_SESSION, HOST_IP, HOST_PORT);
    exo_device_poll(&dev);
    exo_packet p;
    CHECK(last_sample(&p)); /* still a valid packet */
    CHECK_EQ(p.sample.status, EXO_STATUS_LOCKED_LEFT | EXO_STATUS_LOCKED_RIGHT
                                  | EXO_STATUS_HARD_STOP_LEFT | EXO_STATUS_HARD_STOP_RIGHT
                                  | EXO_STATUS_ENCODER_FAULT | EXO_STATUS_SUPPLY_FAULT
                                  | EXO_STATUS_WATCHDOG_RELEASED);
    CHECK_EQ(p.sample.has_truth, 1);
    CHECK(p.sample.truth.progress == 0.25);
    CHECK_EQ(p.sample.truth.lift_index, 7);
    CHECK(memcmp(p.sample.truth.activity, "walk", 4) == 0);
    CHECK_EQ(fb.spi_wrong_shape, 0);
    CHECK_EQ(fb.spi_calls, 3); /* three 4-frame transfers on chip 0 */

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
    learn_host_and_stream();
    commands_and_watchdog();
    watchdog_phases();
    sessions_and_ports();
    timing();
    rate_factor();
    board_status_truth_and_encoders();
}
