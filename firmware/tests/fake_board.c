/*
 * fake_board.c - see fake_board.h.
 */
#include "fake_board.h"

#include <string.h>

int fake_parity_even(uint16_t frame)
{
    unsigned ones = 0;
    for (unsigned bit = 0; bit < 16; bit++)
        ones += ((unsigned)frame >> bit) & 1u;
    return ones % 2u == 0;
}

static uint16_t with_parity(uint16_t v)
{
    v = (uint16_t)(v & 0x7FFFu);
    return fake_parity_even(v) ? v : (uint16_t)(v | 0x8000u);
}

void fake_init(fake_board *f)
{
    memset(f, 0, sizeof *f);
    f->now = 1000000; /* an arbitrary origin, not 0 */
    f->heartbeat_level = -1;
    for (unsigned i = 0; i < 4; i++) {
        f->enc[i].angle = (uint16_t)(1000u * (i + 1) + 7u);
        f->enc[i].diag = 0x0100u | 0x80u; /* offset compensation done, AGC 128 */
        f->enc[i].magnitude = 0x1000u;
    }
    for (unsigned i = 0; i < 8; i++)
        f->random[i] = (uint8_t)(0xA0u + i);
}

/* One 16-bit frame through encoder `e`: out goes the previous command's answer, in
 * comes this command (datasheet: the bus is pipelined). */
static uint16_t frame(fake_board *f, fake_encoder *e, uint16_t cmd)
{
    uint16_t out = e->pending;
    f->frames++;
    if (e->n_log < FAKE_FRAME_LOG)
        e->log[e->n_log++] = cmd;
    uint16_t data = 0;
    int clear = 0;
    if (!fake_parity_even(cmd)) {
        f->frames_bad_parity++;
        e->error_flag = 1;
        e->error_reg |= 4u;
    } else if (cmd & 0x4000u) {
        switch (cmd & 0x3FFFu) {
        case 0x3FFF:
            data = (uint16_t)(e->angle & 0x3FFFu);
            break;
        case 0x3FFE:
            data = e->magnitude;
            break;
        case 0x3FFD:
            data = e->diag;
            break;
        case 0x0001:
            data = e->error_reg;
            clear = 1;
            break;
        default:
            e->error_flag = 1; /* a register the core has no reason to read */
            e->error_reg |= 2u;
        }
    } else if (cmd != 0x0000) {
        e->error_flag = 1; /* the core never writes */
        e->error_reg |= 2u;
    }
    uint16_t answer = with_parity((uint16_t)(data | (e->error_flag ? 0x4000u : 0u)));
    if (e->corrupt_angle && (cmd & 0x3FFFu) == 0x3FFF && (cmd & 0x4000u))
        answer ^= 0x0001u; /* one data bit flipped in transit: parity now wrong */
    if (clear) {
        e->error_flag = 0;
        e->error_reg = 0;
    }
    e->pending = answer;
    return out;
}

static uint64_t now_us(void *ctx) { return ((fake_board *)ctx)->now; }

static int spi_transfer(void *ctx, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n)
{
    fake_board *f = ctx;
    f->spi_calls++;
    if (f->daisy_chain ? (chip != 0 || n != 4) : (chip > 3 || n != 1)) {
        f->spi_wrong_shape++;
        return -1;
    }
    if (f->bus_fail)
        return -1;
    for (size_t i = 0; i < n; i++)
        rx[i] = frame(f, &f->enc[f->daisy_chain ? i : chip], tx[i]);
    return 0;
}

static void set_solenoids(void *ctx, int left, int right)
{
    fake_board *f = ctx;
    f->left = left;
    f->right = right;
    f->solenoid_calls++;
    if (left || right)
        f->energise_calls++;
}

static int send(void *ctx, const uint8_t *data, size_t len, exo_endpoint to)
{
    fake_board *f = ctx;
    f->now += f->send_delay_us;
    if (f->send_fail)
        return -1;
    fake_datagram *d = &f->sent[f->n_sent % FAKE_QUEUE];
    memset(d, 0, sizeof *d);
    memcpy(d->data, data, len < sizeof d->data ? len : sizeof d->data);
    d->len = (long)len;
    d->peer = to;
    d->at_us = f->now;
    f->n_sent++;
    return 0;
}

static long receive(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from)
{
    fake_board *f = ctx;
    if (f->receive_error_once) {
        f->receive_error_once = 0;
        return -1;
    }
    if (f->in_count == 0)
        return EXO_RX_NONE;
    fake_datagram *d = &f->inbox[f->in_head];
    f->in_head = (f->in_head + 1u) % FAKE_QUEUE;
    f->in_count--;
    *from = d->peer;
    if ((size_t)d->len > cap)
        return d->len; /* oversize: true length, buffer untouched */
    memcpy(buf, d->data, (size_t)d->len);
    return d->len;
}

static int random_bytes(void *ctx, uint8_t *out, size_t n)
{
    fake_board *f = ctx;
    if (f->random_fail)
        return -1;
    if (f->random_zero_draws > 0) {
        f->random_zero_draws--;
        memset(out, 0, n);
        return 0;
    }
    for (size_t i = 0; i < n; i++)
        out[i] = (uint8_t)(f->random[i % sizeof f->random] + f->random_draws);
    f->random_draws++; /* every draw differs from the one before (challenges) */
    return 0;
}

static void kick(void *ctx) { ((fake_board *)ctx)->kicks++; }

static void heartbeat(void *ctx, int level)
{
    fake_board *f = ctx;
    if (level != f->heartbeat_level)
        f->heartbeat_edges++;
    f->heartbeat_level = level;
}

static uint32_t sense_status(void *ctx) { return ((fake_board *)ctx)->status; }

static int truth(void *ctx, exo_truth *out)
{
    fake_board *f = ctx;
    if (!f->truth_on)
        return 0;
    *out = f->truth;
    return 1;
}

exo_board fake_interface(fake_board *f, int optional)
{
    exo_board b;
    memset(&b, 0, sizeof b);
    b.ctx = f;
    b.now_us = now_us;
    b.spi_transfer = spi_transfer;
    b.set_solenoids = set_solenoids;
    b.send = send;
    b.receive = receive;
    b.random_bytes = random_bytes;
    if (optional) {
        b.kick_watchdog = kick;
        b.sense_status = sense_status;
        b.truth = truth;
        b.heartbeat = heartbeat;
    }
    return b;
}

void fake_push(fake_board *f, const uint8_t *data, long len, uint32_t ip, uint16_t port)
{
    if (f->in_count == FAKE_QUEUE)
        return;
    fake_datagram *d = &f->inbox[(f->in_head + f->in_count) % FAKE_QUEUE];
    memset(d, 0, sizeof *d);
    size_t stored = (size_t)len < sizeof d->data ? (size_t)len : sizeof d->data;
    memcpy(d->data, data, stored);
    d->len = len;
    d->peer.ip = ip;
    d->peer.port = port;
    f->in_count++;
}

const fake_datagram *fake_last_sent(const fake_board *f)
{
    return f->n_sent ? &f->sent[(f->n_sent - 1u) % FAKE_QUEUE] : NULL;
}
