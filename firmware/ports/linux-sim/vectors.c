/*
 * vectors.c - `exostudy-device-vectors HELLO_HEX COMMAND_HEX`: the C side of the
 * protocol's documented test vectors (docs/device-protocol.md), for
 * tests/controller/device/test_protocol.py, which compares every line with the
 * document byte for byte. The same tests run against the Python implementation, so
 * the two cannot drift apart.
 *
 * It prints, one per line, `NAME HEX` or `NAME VALUE`:
 *   wire_sample, wire_sample_truth, wire_command, wire_hello   the core's encoders
 *   device_sample, device_sample_truth   the same SAMPLEs as the whole device makes
 *       them: a device booted with the document's session, fed the document's HELLO
 *       and COMMAND (and, for the first, one forged and two replayed commands) on a
 *       simulated clock, with the emulated encoders showing the document's counts
 *   decode_ok_NAME 1|0       the core's decoder accepts the document's packet
 *   device_hello_streams 1|0, device_command_energises 1|0   the device acts on them
 *   decoder_flips_rejected N TOTAL, device_flips_ignored N TOTAL   every one-bit
 *       change of the HELLO and the COMMAND is refused (and changes nothing)
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
#define MAX_QUEUE 8

static const uint16_t DOC_COUNTS[4] = {3100, 3105, 12900, 12890};

typedef struct {
    uint64_t clock_us;
    as5048a chips[4];
    int with_truth;
    int solenoid_left, solenoid_right, ever_energised;
    uint8_t queue[MAX_QUEUE][EXO_MAX_PACKET + 1];
    size_t queue_len[MAX_QUEUE];
    unsigned queued, delivered;
    uint8_t last_sent[EXO_MAX_PACKET];
    size_t last_len;
    unsigned sends;
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
    if (left || right)
        f->ever_energised = 1;
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
        return 0;
    size_t len = f->queue_len[f->delivered];
    if (len <= cap)
        memcpy(buf, f->queue[f->delivered], len);
    f->delivered++;
    from->ip = HOST_IP;
    from->port = HOST_PORT;
    return (long)len;
}

static int f_random(void *ctx, uint8_t *out, size_t n) {
    (void)ctx;
    for (size_t i = 0; i < n; i++) /* little-endian: the core reads exo_le64 */
        out[i] = (uint8_t)(DEVICE_SESSION >> (8u * (i % 8u)));
    return 0;
}

static uint32_t f_status(void *ctx) {
    (void)ctx;
    return EXO_STATUS_LOCKED_LEFT;
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

static void boot(int with_truth) {
    memset(&board_state, 0, sizeof board_state);
    board_state.clock_us = 5000000u; /* any origin: the stream starts at the HELLO */
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
    b.truth = f_truth;
    exo_config cfg;
    memset(&cfg, 0, sizeof cfg);
    for (int i = 0; i < EXO_KEY_BYTES; i++)
        cfg.key[i] = (uint8_t)i;
    cfg.host_ip = HOST_IP;
    if (exo_device_init(&dev, &b, &cfg) != 0) {
        fprintf(stderr, "exostudy-device-vectors: init failed\n");
        exit(1);
    }
}

static void deliver(const uint8_t *data, size_t len) {
    if (board_state.queued >= MAX_QUEUE)
        exit(1);
    memcpy(board_state.queue[board_state.queued], data, len);
    board_state.queue_len[board_state.queued++] = len;
    exo_device_poll(&dev);
}

static size_t parse_hex(const char *s, uint8_t *out, size_t cap) {
    size_t n = 0;
    while (*s) {
        while (*s == ' ' || *s == '\n')
            s++;
        if (!*s)
            break;
        unsigned v;
        if (n >= cap || sscanf(s, "%2x", &v) != 1)
            exit(2);
        out[n++] = (uint8_t)v;
        s += 2;
    }
    return n;
}

static void print_hex(const char *name, const uint8_t *d, size_t n) {
    printf("%s ", name);
    for (size_t i = 0; i < n; i++)
        printf("%02x", d[i]);
    printf("\n");
}

/* The device's SAMPLE 258 (t = 2.58 s): HELLO at the stream's start, the COMMAND
 * 5 ms before sample 258 is due; with `drops`, a forged copy of the command first and
 * two replays after it. */
static void device_sample(const char *name, int with_truth, int drops, const uint8_t *hello,
                          size_t hello_len, const uint8_t *command, size_t command_len) {
    boot(with_truth);
    uint64_t t0 = board_state.clock_us;
    deliver(hello, hello_len);
    for (uint64_t k = 1; k < 258; k++) {
        board_state.clock_us = t0 + k * 10000u;
        exo_device_poll(&dev);
    }
    board_state.clock_us = t0 + 2575000u;
    if (drops) {
        uint8_t forged[EXO_MAX_PACKET];
        memcpy(forged, command, command_len);
        forged[command_len - 1] ^= 0x01;
        deliver(forged, command_len);
    }
    deliver(command, command_len);
    if (drops) {
        deliver(command, command_len);
        deliver(command, command_len);
    }
    board_state.clock_us = t0 + 2580000u;
    exo_device_poll(&dev);
    print_hex(name, board_state.last_sent, board_state.last_len);
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: exostudy-device-vectors HELLO_HEX COMMAND_HEX\n");
        return 2;
    }
    uint8_t hello[EXO_MAX_PACKET], command[EXO_MAX_PACKET], buf[EXO_MAX_PACKET];
    size_t hello_len = parse_hex(argv[1], hello, sizeof hello);
    size_t command_len = parse_hex(argv[2], command, sizeof command);
    uint8_t key_bytes[EXO_KEY_BYTES];
    for (int i = 0; i < EXO_KEY_BYTES; i++)
        key_bytes[i] = (uint8_t)i;
    exo_hmac_key key;
    exo_hmac_set_key(&key, key_bytes, sizeof key_bytes);

    /* The core's encoders. */
    exo_sample_fields s;
    memset(&s, 0, sizeof s);
    s.t_us = 2580000u;
    s.seq = 258;
    s.status = EXO_STATUS_SOLENOID_LEFT | EXO_STATUS_LOCKED_LEFT;
    memcpy(s.counts, DOC_COUNTS, sizeof s.counts);
    s.auth_drops = 1;
    s.replay_drops = 2;
    size_t n = exo_wire_encode_sample(&key, &s, DEVICE_SESSION, HOST_SESSION, buf, sizeof buf);
    print_hex("wire_sample", buf, n);
    uint8_t sample[EXO_MAX_PACKET];
    size_t sample_len = n;
    memcpy(sample, buf, n);
    s.auth_drops = s.replay_drops = 0;
    s.has_truth = 1;
    s.truth.progress = 0.5;
    s.truth.lift_index = 3;
    s.truth.activity_len = 5;
    memcpy(s.truth.activity, "squat", 5);
    n = exo_wire_encode_sample(&key, &s, DEVICE_SESSION, HOST_SESSION, buf, sizeof buf);
    print_hex("wire_sample_truth", buf, n);
    uint8_t truth[EXO_MAX_PACKET];
    size_t truth_len = n;
    memcpy(truth, buf, n);
    n = exo_wire_encode_command(&key, 7, 1, 258, EXO_LOCK_LEFT, HOST_SESSION, DEVICE_SESSION, buf,
                                sizeof buf);
    print_hex("wire_command", buf, n);
    n = exo_wire_encode_hello(&key, 1, HOST_SESSION, 0, buf, sizeof buf);
    print_hex("wire_hello", buf, n);

    /* The decoder accepts the document's four packets... */
    exo_packet pkt;
    printf("decode_ok_sample %d\n", exo_wire_decode(&key, sample, sample_len, &pkt) == EXO_DROP_NONE);
    printf("decode_ok_sample_truth %d\n",
           exo_wire_decode(&key, truth, truth_len, &pkt) == EXO_DROP_NONE);
    printf("decode_ok_command %d\n",
           exo_wire_decode(&key, command, command_len, &pkt) == EXO_DROP_NONE &&
               pkt.type == EXO_TYPE_COMMAND && pkt.host_seq == 7 && pkt.echo_valid &&
               pkt.echo_seq == 258 && pkt.locks == EXO_LOCK_LEFT &&
               pkt.sender == HOST_SESSION && pkt.receiver == DEVICE_SESSION);
    printf("decode_ok_hello %d\n",
           exo_wire_decode(&key, hello, hello_len, &pkt) == EXO_DROP_NONE &&
               pkt.type == EXO_TYPE_HELLO && pkt.host_seq == 1 && pkt.sender == HOST_SESSION &&
               pkt.receiver == 0);

    /* ... and refuses each of them with any one bit changed. */
    const uint8_t *all[4] = {sample, truth, command, hello};
    size_t lens[4] = {sample_len, truth_len, command_len, hello_len};
    unsigned rejected = 0, total = 0;
    for (int p = 0; p < 4; p++) {
        for (size_t bit = 0; bit < 8 * lens[p]; bit++) {
            memcpy(buf, all[p], lens[p]);
            buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
            total++;
            rejected += exo_wire_decode(&key, buf, lens[p], &pkt) != EXO_DROP_NONE;
        }
    }
    printf("decoder_flips_rejected %u %u\n", rejected, total);

    /* The whole device: the document's SAMPLEs, made from the document's HELLO and
     * COMMAND, encoders and clock. */
    device_sample("device_sample", 0, 1, hello, hello_len, command, command_len);
    device_sample("device_sample_truth", 1, 0, hello, hello_len, command, command_len);

    /* It acts on the document's HELLO (starts streaming) and COMMAND (energises the
     * left solenoid at the next sample)... */
    boot(0);
    deliver(hello, hello_len);
    int streams = dev.stats.hellos == 1 && board_state.sends == 1;
    printf("device_hello_streams %d\n", streams);
    board_state.clock_us += 5000u;
    deliver(command, command_len);
    board_state.clock_us += 5000u;
    exo_device_poll(&dev);
    printf("device_command_energises %d\n", dev.stats.commands == 1 &&
                                                board_state.solenoid_left &&
                                                !board_state.solenoid_right);

    /* ... and ignores every one-bit change of them: a changed HELLO starts nothing, a
     * changed COMMAND (after the real HELLO) energises nothing; each is counted. */
    unsigned ignored = 0;
    total = 0;
    for (size_t bit = 0; bit < 8 * hello_len; bit++) {
        boot(0);
        memcpy(buf, hello, hello_len);
        buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
        deliver(buf, hello_len);
        const exo_stats *st = &dev.stats;
        uint64_t drops = st->replayed + st->foreign + st->unexpected;
        for (int r = 0; r < EXO_DROP_REASONS; r++)
            drops += st->malformed[r];
        total++;
        ignored += !st->host_known && board_state.sends == 0 && st->hellos == 0 && drops == 1;
    }
    for (size_t bit = 0; bit < 8 * command_len; bit++) {
        boot(0);
        deliver(hello, hello_len);
        memcpy(buf, command, command_len);
        buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
        board_state.clock_us += 5000u;
        deliver(buf, command_len);
        board_state.clock_us += 5000u;
        exo_device_poll(&dev);
        const exo_stats *st = &dev.stats;
        uint64_t drops = st->replayed + st->foreign + st->unexpected;
        for (int r = 0; r < EXO_DROP_REASONS; r++)
            drops += st->malformed[r];
        total++;
        ignored += st->commands == 0 && !board_state.ever_energised && drops == 1;
    }
    printf("device_flips_ignored %u %u\n", ignored, total);
    return 0;
}
