/*
 * vectors.c - `exostudy-device-vectors NAME=HEX ...`: the C side of the protocol's
 * documented test vectors (docs/device-protocol.md), for
 * tests/controller/device/test_protocol.py, which passes the document's eight blocks
 * (sample, sample_truth, hello, challenge, join, command, command_heartbeat, version)
 * and compares every line with the document byte for byte. The same tests run against
 * the Python implementation, so the two cannot drift apart.
 *
 * It prints, one per line, `NAME HEX` or `NAME VALUE`:
 *   wire_NAME (all eight)     the core's encoders, given the document's fields
 *   decode_ok_NAME 1|0        the core's decoder accepts the document's packet with
 *                             the document's fields
 *   decoder_flips_rejected N TOTAL   every one-bit change of the eight is refused
 *   device_challenge, device_sample, device_sample_truth   the packets as the whole
 *       device makes them: booted with the document's session (and challenge, drawn
 *       second; identity from its config), fed the document's HELLO and JOIN on a
 *       simulated clock, then (by a second JOIN of the same host, which resets
 *       host_seq below 7) a lock-left COMMAND so that sample 258 has the left solenoid
 *       on; for the first, also one forged, two replayed and three stale datagrams
 *   device_join_streams 1|0   the document's JOIN starts the stream (sample 0 to it)
 *   device_command_energises 1|0   the document's COMMAND 7 energises the left
 *       solenoid from the next period, COMMAND 8 both and stops the heartbeat
 *   device_flips_ignored N TOTAL   every one-bit change of the HELLO, JOIN and both
 *       COMMANDs, delivered in its place in the exchange, is dropped, counted once
 *       and changes nothing
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "as5048a_chip.h"
#include "exo_device.h"

#define DEVICE_SESSION 0x1122334455667788ull
#define HOST_SESSION 0x0123456789abcdefull
#define HOST_IP 0x7F000001u
#define HOST_PORT 40000u
#define MAX_QUEUE 16
#define N_VECTORS 8

static const char *const NAMES[N_VECTORS] = {"sample", "sample_truth", "hello", "challenge",
                                             "join", "command", "command_heartbeat", "version"};
enum { V_SAMPLE, V_TRUTH, V_HELLO, V_CHALLENGE, V_JOIN, V_COMMAND, V_HEARTBEAT, V_VERSION };

static const uint16_t DOC_COUNTS[4] = {3100, 3105, 12900, 12890};

typedef struct {
    uint64_t clock_us;
    as5048a chips[4];
    int with_truth;
    int solenoid_left, solenoid_right, ever_left, ever_right;
    unsigned heartbeat_edges;
    uint8_t queue[MAX_QUEUE][EXO_MAX_PACKET + 1];
    size_t queue_len[MAX_QUEUE];
    unsigned queued, delivered;
    uint8_t last_sent[EXO_MAX_PACKET];
    size_t last_len;
    unsigned sends;
    unsigned draws;
} fake;

static uint64_t f_now(void *ctx) { return ((fake *)ctx)->clock_us; }

static int f_spi(void *ctx, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n) {
    fake *f = ctx;
    if (chip >= 4 || n > 4 - chip)
        return -1;
    for (size_t i = 0; i < n; i++)
        rx[i] = as5048a_frame(&f->chips[chip + i], tx[i]);
    return 0;
}

static void f_solenoids(void *ctx, int left, int right) {
    fake *f = ctx;
    f->solenoid_left = left;
    f->solenoid_right = right;
    f->ever_left |= left;
    f->ever_right |= right;
}

static int f_send(void *ctx, const uint8_t *data, size_t len, exo_endpoint to) {
    fake *f = ctx;
    (void)to;
    if (len > sizeof f->last_sent)
        return -1;
    memcpy(f->last_sent, data, len);
    f->last_len = len;
    f->sends++;
    return 0;
}

static long f_receive(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from) {
    fake *f = ctx;
    if (f->delivered >= f->queued)
        return EXO_RX_NONE;
    unsigned slot = f->delivered % MAX_QUEUE;
    size_t len = f->queue_len[slot];
    if (len <= cap)
        memcpy(buf, f->queue[slot], len);
    f->delivered++;
    from->ip = HOST_IP;
    from->port = HOST_PORT;
    return (long)len;
}

/* Draw 0: the document's device session; draw 1: its challenge a0..af; later draws:
 * other challenges. */
static int f_random(void *ctx, uint8_t *out, size_t n) {
    fake *f = ctx;
    for (size_t i = 0; i < n; i++) {
        if (f->draws == 0)
            out[i] = (uint8_t)(DEVICE_SESSION >> (8u * (i % 8u))); /* read little-endian */
        else if (f->draws == 1)
            out[i] = (uint8_t)(0xA0u + i);
        else
            out[i] = (uint8_t)(0x30u + 7u * f->draws + i);
    }
    f->draws++;
    return 0;
}

static uint32_t f_status(void *ctx) {
    (void)ctx;
    return EXO_STATUS_LOCKED_LEFT;
}

static void f_heartbeat(void *ctx, int level) {
    (void)level;
    ((fake *)ctx)->heartbeat_edges++;
}

static int f_truth(void *ctx, exo_truth *out) {
    fake *f = ctx;
    if (!f->with_truth)
        return 0;
    out->progress = 0.5;
    out->lift_index = 3;
    out->activity_len = 5;
    memcpy(out->activity, "squat", 5);
    return 1;
}

static exo_device dev;
static fake board_state;
static exo_hmac_key key;
static uint8_t vec[N_VECTORS][EXO_MAX_PACKET + 1];
static size_t vec_len[N_VECTORS];

static void boot(int with_truth) {
    memset(&board_state, 0, sizeof board_state);
    board_state.clock_us = 5000000u; /* any origin: the stream starts at the JOIN */
    board_state.with_truth = with_truth;
    for (int i = 0; i < 4; i++) {
        as5048a_reset(&board_state.chips[i]);
        as5048a_set_magnet(&board_state.chips[i], DOC_COUNTS[i], 0);
    }
    exo_board b;
    memset(&b, 0, sizeof b);
    b.ctx = &board_state;
    b.now_us = f_now;
    b.spi_transfer = f_spi;
    b.set_solenoids = f_solenoids;
    b.send = f_send;
    b.receive = f_receive;
    b.random_bytes = f_random;
    b.sense_status = f_status;
    b.heartbeat = f_heartbeat;
    b.truth = f_truth;
    exo_config cfg;
    memset(&cfg, 0, sizeof cfg);
    for (int i = 0; i < EXO_KEY_BYTES; i++)
        cfg.key[i] = (uint8_t)i;
    cfg.host_ip = HOST_IP;
    for (int i = 0; i < 12; i++)
        cfg.unique_id[i] = (uint8_t)(0x10 + i);
    memcpy(cfg.firmware, "exostudy-c 3.0", 14);
    if (exo_device_init(&dev, &b, &cfg) != 0) {
        fprintf(stderr, "exostudy-device-vectors: init failed\n");
        exit(1);
    }
}

static void deliver(const uint8_t *data, size_t len) {
    unsigned slot = board_state.queued % MAX_QUEUE;
    memcpy(board_state.queue[slot], data, len);
    board_state.queue_len[slot] = len;
    board_state.queued++;
    exo_device_poll(&dev);
}

/* Move the clock to stream time `t_us` (the stream starts at t0), polling every ms. */
static uint64_t t0;
static void run_to(uint64_t t_us) {
    while (board_state.clock_us + 1000u <= t0 + t_us) {
        board_state.clock_us += 1000u;
        exo_device_poll(&dev);
    }
    board_state.clock_us = t0 + t_us;
    exo_device_poll(&dev);
}

static uint64_t all_drops(void) {
    const exo_stats *st = &dev.stats;
    uint64_t n = st->replayed + st->stale_echo + st->foreign + st->flood + st->unexpected;
    for (int r = 0; r < EXO_DROP_REASONS; r++)
        n += st->malformed[r];
    return n;
}

static void print_hex(const char *name, const uint8_t *d, size_t n) {
    printf("%s ", name);
    for (size_t i = 0; i < n; i++)
        printf("%02x", d[i]);
    printf("\n");
}

static int last_sent_is(unsigned type, uint32_t seq) {
    exo_packet p;
    return exo_wire_decode(&key, board_state.last_sent, board_state.last_len, &p) == EXO_DROP_NONE
           && p.type == type && (type != EXO_TYPE_SAMPLE || p.sample.seq == seq);
}

/* The document's HELLO at boot time, JOIN 1 ms later (stream starts there). */
static void hello_and_join(uint8_t *challenge_out, size_t *challenge_len) {
    deliver(vec[V_HELLO], vec_len[V_HELLO]);
    if (challenge_out) {
        memcpy(challenge_out, board_state.last_sent, board_state.last_len);
        *challenge_len = board_state.last_len;
    }
    board_state.clock_us += 1000u;
    t0 = board_state.clock_us;
    deliver(vec[V_JOIN], vec_len[V_JOIN]);
}

/* Up to SAMPLE 258 (not sent yet): with `lock`, a second JOIN of the host (host_seq 2)
 * and a lock-left COMMAND (host_seq 3) answering sample 256; with `drops`, a forged
 * copy of COMMAND 7, the document's JOIN replayed twice (spent), and three COMMANDs
 * (host_seq 4..6) echoing sample 0, long gone. */
static void up_to_258(int lock, int drops) {
    uint8_t d[EXO_MAX_PACKET];
    size_t n;
    if (lock) {
        run_to(100000);
        n = exo_wire_encode_hello(&key, 1, HOST_SESSION, 0, d, sizeof d);
        deliver(d, n);
        exo_packet c;
        if (exo_wire_decode(&key, board_state.last_sent, board_state.last_len, &c) != EXO_DROP_NONE
            || c.type != EXO_TYPE_CHALLENGE)
            exit(3);
        n = exo_wire_encode_join(&key, 2, c.challenge.challenge, HOST_SESSION, DEVICE_SESSION, d,
                                 sizeof d);
        deliver(d, n);
    }
    if (drops) {
        run_to(200000);
        memcpy(d, vec[V_COMMAND], vec_len[V_COMMAND]);
        d[vec_len[V_COMMAND] - 1] ^= 0x01;
        deliver(d, vec_len[V_COMMAND]);
        deliver(vec[V_JOIN], vec_len[V_JOIN]);
        deliver(vec[V_JOIN], vec_len[V_JOIN]);
        for (uint32_t seq = 4; seq <= 6; seq++) {
            n = exo_wire_encode_command(&key, seq, 0, EXO_LOCK_LEFT, 0, HOST_SESSION,
                                        DEVICE_SESSION, d, sizeof d);
            deliver(d, n);
        }
    }
    run_to(2561000u);
    if (lock) {
        n = exo_wire_encode_command(&key, 3, 256, EXO_LOCK_LEFT, 0, HOST_SESSION, DEVICE_SESSION,
                                    d, sizeof d);
        deliver(d, n);
    }
    run_to(2579000u);
}

/* What the device has done so far that a dropped datagram must not change. */
typedef struct {
    uint64_t hellos, joins, commands, challenges, drops;
    unsigned sends, edges;
    int ever_left, ever_right, streaming;
} footprint;

static footprint now_footprint(void) {
    footprint f;
    memset(&f, 0, sizeof f); /* padding too: footprints are compared with memcmp */
    f.hellos = dev.stats.hellos;
    f.joins = dev.stats.joins;
    f.commands = dev.stats.commands;
    f.challenges = dev.stats.challenges;
    f.drops = all_drops();
    f.sends = board_state.sends;
    f.edges = board_state.heartbeat_edges;
    f.ever_left = board_state.ever_left;
    f.ever_right = board_state.ever_right;
    f.streaming = dev.streaming;
    return f;
}

static exo_device saved_dev;
static fake saved_board;
static void save(void) {
    saved_dev = dev;
    saved_board = board_state;
}
static void restore(void) {
    dev = saved_dev;
    board_state = saved_board;
}

/* Every one-bit change of vector `v`, delivered instead of it from the saved state,
 * then two more sample periods: exactly one more drop, nothing else changed (samples
 * and heartbeat edges go on as without it). Returns how many were ignored. */
static unsigned flips_ignored(int v, unsigned *total) {
    restore();
    exo_device_poll(&dev); /* the reference: the same polls, nothing delivered */
    board_state.clock_us += 20000u;
    exo_device_poll(&dev);
    footprint want = now_footprint();
    want.drops += 1;
    unsigned ignored = 0;
    uint8_t buf[EXO_MAX_PACKET];
    for (size_t bit = 0; bit < 8 * vec_len[v]; bit++) {
        restore();
        memcpy(buf, vec[v], vec_len[v]);
        buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
        deliver(buf, vec_len[v]);
        board_state.clock_us += 20000u;
        exo_device_poll(&dev);
        footprint got = now_footprint();
        (*total)++;
        ignored += memcmp(&got, &want, sizeof got) == 0;
    }
    return ignored;
}

int main(int argc, char **argv) {
    for (int a = 1; a < argc; a++) {
        const char *eq = strchr(argv[a], '=');
        int v = -1;
        for (int i = 0; eq && i < N_VECTORS; i++)
            if (strlen(NAMES[i]) == (size_t)(eq - argv[a]) && strncmp(argv[a], NAMES[i], (size_t)(eq - argv[a])) == 0)
                v = i;
        size_t hex = eq ? strlen(eq + 1) : 0;
        if (v < 0 || hex % 2 || hex / 2 > EXO_MAX_PACKET) {
            fprintf(stderr, "usage: exostudy-device-vectors NAME=HEX ... (NAME: sample, "
                            "sample_truth, hello, challenge, join, command, "
                            "command_heartbeat, version)\n");
            return 2;
        }
        for (size_t i = 0; i < hex / 2; i++) {
            unsigned byte;
            if (sscanf(eq + 1 + 2 * i, "%2x", &byte) != 1)
                return 2;
            vec[v][i] = (uint8_t)byte;
        }
        vec_len[v] = hex / 2;
    }
    for (int v = 0; v < N_VECTORS; v++)
        if (vec_len[v] == 0) {
            fprintf(stderr, "exostudy-device-vectors: %s=HEX missing\n", NAMES[v]);
            return 2;
        }
    uint8_t key_bytes[EXO_KEY_BYTES];
    for (int i = 0; i < EXO_KEY_BYTES; i++)
        key_bytes[i] = (uint8_t)i;
    exo_hmac_set_key(&key, key_bytes, sizeof key_bytes);

    /* The core's encoders, from the document's fields. */
    uint8_t buf[EXO_MAX_PACKET];
    exo_sample_fields s;
    memset(&s, 0, sizeof s);
    s.t_us = 2580000u;
    s.seq = 258;
    s.status = EXO_STATUS_SOLENOID_LEFT | EXO_STATUS_LOCKED_LEFT;
    memcpy(s.counts, DOC_COUNTS, sizeof s.counts);
    s.auth_drops = 1;
    s.replay_drops = 2;
    s.stale_drops = 3;
    print_hex("wire_sample", buf, exo_wire_encode_sample(&key, &s, DEVICE_SESSION, HOST_SESSION, buf, sizeof buf));
    s.auth_drops = s.replay_drops = s.stale_drops = 0;
    s.has_truth = 1;
    s.truth.progress = 0.5;
    s.truth.lift_index = 3;
    s.truth.activity_len = 5;
    memcpy(s.truth.activity, "squat", 5);
    print_hex("wire_sample_truth", buf,
              exo_wire_encode_sample(&key, &s, DEVICE_SESSION, HOST_SESSION, buf, sizeof buf));
    print_hex("wire_hello", buf, exo_wire_encode_hello(&key, 5, HOST_SESSION, 0, buf, sizeof buf));
    exo_challenge_fields cf;
    memset(&cf, 0, sizeof cf);
    cf.hello_seq = 5;
    cf.lifetime_ms = 1000;
    for (int i = 0; i < 16; i++)
        cf.challenge[i] = (uint8_t)(0xA0 + i);
    for (int i = 0; i < 12; i++)
        cf.unique_id[i] = (uint8_t)(0x10 + i);
    memcpy(cf.firmware, "exostudy-c 3.0", 14);
    print_hex("wire_challenge", buf,
              exo_wire_encode_challenge(&key, &cf, DEVICE_SESSION, HOST_SESSION, buf, sizeof buf));
    print_hex("wire_join", buf,
              exo_wire_encode_join(&key, 6, cf.challenge, HOST_SESSION, DEVICE_SESSION, buf, sizeof buf));
    print_hex("wire_command", buf, exo_wire_encode_command(&key, 7, 258, EXO_LOCK_LEFT, 0, HOST_SESSION,
                                                           DEVICE_SESSION, buf, sizeof buf));
    print_hex("wire_command_heartbeat", buf,
              exo_wire_encode_command(&key, 8, 259, EXO_LOCK_LEFT | EXO_LOCK_RIGHT, 1, HOST_SESSION,
                                      DEVICE_SESSION, buf, sizeof buf));
    print_hex("wire_version", buf, exo_wire_encode_version(&key, 3, 3, buf, sizeof buf));

    /* The decoder accepts the document's eight packets with their fields... */
    exo_packet p;
    int ok[N_VECTORS];
    for (int v = 0; v < N_VECTORS; v++)
        ok[v] = exo_wire_decode(&key, vec[v], vec_len[v], &p) == EXO_DROP_NONE;
    exo_wire_decode(&key, vec[V_SAMPLE], vec_len[V_SAMPLE], &p);
    ok[V_SAMPLE] = ok[V_SAMPLE] && p.type == EXO_TYPE_SAMPLE && p.sample.seq == 258
                   && p.sample.auth_drops == 1 && p.sample.replay_drops == 2
                   && p.sample.stale_drops == 3 && p.sender == DEVICE_SESSION;
    exo_wire_decode(&key, vec[V_TRUTH], vec_len[V_TRUTH], &p);
    ok[V_TRUTH] = ok[V_TRUTH] && p.sample.has_truth && p.sample.truth.lift_index == 3;
    exo_wire_decode(&key, vec[V_HELLO], vec_len[V_HELLO], &p);
    ok[V_HELLO] = ok[V_HELLO] && p.type == EXO_TYPE_HELLO && p.host_seq == 5
                  && p.sender == HOST_SESSION && p.receiver == 0;
    exo_wire_decode(&key, vec[V_CHALLENGE], vec_len[V_CHALLENGE], &p);
    ok[V_CHALLENGE] = ok[V_CHALLENGE] && p.type == EXO_TYPE_CHALLENGE
                      && memcmp(&p.challenge, &cf, sizeof cf) == 0 && p.receiver == HOST_SESSION;
    exo_wire_decode(&key, vec[V_JOIN], vec_len[V_JOIN], &p);
    ok[V_JOIN] = ok[V_JOIN] && p.type == EXO_TYPE_JOIN && p.host_seq == 6
                 && memcmp(p.join_challenge, cf.challenge, 16) == 0 && p.receiver == DEVICE_SESSION;
    exo_wire_decode(&key, vec[V_COMMAND], vec_len[V_COMMAND], &p);
    ok[V_COMMAND] = ok[V_COMMAND] && p.type == EXO_TYPE_COMMAND && p.host_seq == 7 && p.echo_seq == 258
                    && p.locks == EXO_LOCK_LEFT && !p.stop_heartbeat && p.sender == HOST_SESSION;
    exo_wire_decode(&key, vec[V_HEARTBEAT], vec_len[V_HEARTBEAT], &p);
    ok[V_HEARTBEAT] = ok[V_HEARTBEAT] && p.type == EXO_TYPE_COMMAND && p.host_seq == 8
                      && p.echo_seq == 259 && p.locks == 3u && p.stop_heartbeat;
    exo_wire_decode(&key, vec[V_VERSION], vec_len[V_VERSION], &p);
    ok[V_VERSION] = ok[V_VERSION] && p.type == EXO_TYPE_VERSION && p.lowest == 3 && p.highest == 3;
    for (int v = 0; v < N_VECTORS; v++)
        printf("decode_ok_%s %d\n", NAMES[v], ok[v]);

    /* ... and refuses each of them with any one bit changed. */
    unsigned rejected = 0, total = 0;
    for (int v = 0; v < N_VECTORS; v++)
        for (size_t bit = 0; bit < 8 * vec_len[v]; bit++) {
            memcpy(buf, vec[v], vec_len[v]);
            buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
            total++;
            rejected += exo_wire_decode(&key, buf, vec_len[v], &p) != EXO_DROP_NONE;
        }
    printf("decoder_flips_rejected %u %u\n", rejected, total);

    /* The whole device: its CHALLENGE and SAMPLEs. */
    uint8_t challenge[EXO_MAX_PACKET];
    size_t challenge_len = 0;
    boot(0);
    hello_and_join(challenge, &challenge_len);
    print_hex("device_challenge", challenge, challenge_len);
    up_to_258(1, 1);
    run_to(2580000u);
    print_hex("device_sample", board_state.last_sent, board_state.last_len);
    boot(1);
    hello_and_join(NULL, NULL);
    up_to_258(1, 0);
    run_to(2580000u);
    print_hex("device_sample_truth", board_state.last_sent, board_state.last_len);

    /* It acts on the document's JOIN (sample 0 at once) and COMMANDs (7: left from the
     * next period; 8: both, heartbeat stopped). */
    boot(0);
    hello_and_join(NULL, NULL);
    printf("device_join_streams %d\n", dev.stats.joins == 1 && last_sent_is(EXO_TYPE_SAMPLE, 0));
    up_to_258(0, 0);
    run_to(2580000u);
    int off_before = !board_state.ever_left && !board_state.ever_right;
    deliver(vec[V_COMMAND], vec_len[V_COMMAND]);
    run_to(2590000u);
    int left = board_state.solenoid_left && !board_state.solenoid_right && dev.stats.commands == 1;
    deliver(vec[V_HEARTBEAT], vec_len[V_HEARTBEAT]);
    unsigned edges = board_state.heartbeat_edges;
    run_to(2600000u);
    int both = board_state.solenoid_left && board_state.solenoid_right && dev.stats.commands == 2
               && board_state.heartbeat_edges == edges;
    printf("device_command_energises %d\n", off_before && left && both);

    /* ... and ignores every one-bit change of the host's four packets, each delivered
     * where the real one would be. */
    unsigned ignored = 0;
    total = 0;
    boot(0);
    save();
    ignored += flips_ignored(V_HELLO, &total);
    boot(0);
    deliver(vec[V_HELLO], vec_len[V_HELLO]);
    board_state.clock_us += 1000u;
    save();
    ignored += flips_ignored(V_JOIN, &total);
    boot(0);
    hello_and_join(NULL, NULL);
    up_to_258(0, 0);
    run_to(2580000u);
    save();
    ignored += flips_ignored(V_COMMAND, &total);
    restore();
    deliver(vec[V_COMMAND], vec_len[V_COMMAND]);
    run_to(2590000u);
    save();
    ignored += flips_ignored(V_HEARTBEAT, &total);
    printf("device_flips_ignored %u %u\n", ignored, total);
    return 0;
}
