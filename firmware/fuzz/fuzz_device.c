/*
 * fuzz_device.c - libFuzzer harness for the device core's state machine
 * (exo_device_init / exo_device_poll) on a fake board with a simulated clock.
 *
 * The input is a program of steps: advance the clock (as a port that polls on time,
 * or as one stalled), deliver a HELLO, JOIN or COMMAND that the harness builds and
 * authenticates with the test key from fields in the input (sessions, sequence
 * numbers, echoed sample, locks, STOP_HEARTBEAT, and challenge bytes taken from the
 * device's last CHALLENGE, from an older one, or from the input), replay an earlier
 * datagram, deliver from a foreign IP, deliver an empty datagram, deliver raw or
 * mutated bytes (re-authenticated or not), or a datagram of another version.
 *
 * Every call the core makes to the board is logged in order, and after EVERY step the
 * log is replayed through an independent model of the protocol document
 * (fz_device_model.c), which checks:
 * - every datagram is counted exactly once, where the document says (a flood drop is
 *   accepted only after 8 datagrams in the current period or the one before);
 * - a solenoid output on requires an authentic COMMAND of the current joined session,
 *   later than every applied host_seq, applied within 100 ms of the send time of the
 *   sample it echoes, and no JOIN since; the outputs are set on only while that sample
 *   was sent at most 100 ms ago (however late the command arrived), follow the latest
 *   applied command while its sample is younger than 100 ms, and both are off once
 *   100 ms + one period have passed since that sample was sent;
 * - a HELLO never changes the session, sequence, destination or outputs: only a JOIN
 *   moves where samples go;
 * - every packet the device sends is valid under the key: SAMPLEs (seq +1 each, to the
 *   latest JOIN's source and session, status matching the outputs, drop counters as
 *   counted), CHALLENGEs (one to the source of every authentic HELLO within the
 *   budget, none otherwise, bytes redrawn when the document says), VERSION (only after an authentic other-version datagram,
 *   at most one per second);
 * - the heartbeat toggles, and does not while an applied STOP_HEARTBEAT is in force.
 * On a violation the harness prints the step and the datagram and aborts (libFuzzer
 * saves the input).
 */
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exo_device.h"
#include "fake_board.h"
#include "fz_device_model.h"
#include "fz_hmac.h"
#include "fz_wire_model.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define HOST_IP 0xC0A80102u
#define OTHER_IP 0xC0A80109u
#define HOST_PORT 50000u
#define MAX_STEPS 200u
#define MAX_EVENTS 512u
#define HISTORY 16u

typedef enum { EV_RX, EV_SEND, EV_SOL, EV_HB, EV_KICK, EV_RAND } ev_kind;

typedef struct {
    ev_kind kind;
    uint64_t at;
    uint8_t data[FZ_MAX_DATAGRAM];
    size_t len;
    uint32_t ip;
    uint16_t port;
    int a, b;
} event;

typedef struct {
    uint8_t data[FZ_MAX_DATAGRAM];
    size_t len;
    uint32_t ip;
    uint16_t port;
} datagram;

/* The board: fake_board first, so that its SPI model (which casts ctx to
 * fake_board *) works on the same context. */
typedef struct {
    fake_board fb;
    int pending;
    datagram in;
    event ev[MAX_EVENTS];
    unsigned n_ev;
    uint64_t rng;
    int left, right;
    int hb_level, hb_known;
} board;

static board B;
static exo_device dev; /* large: static */
static fz_model M;
static uint8_t KEY[32];
static const uint8_t UNIQUE_ID[16] = {0x10, 0x11, 0x12, 0x13, 0x14, 0x15, 0x16, 0x17,
                                      0x18, 0x19, 0x1a, 0x1b, 0, 0, 0, 0};
static const char FIRMWARE[16] = "exo-fuzz 3";

/* The harness's own memory of the conversation (to build datagrams from). */
static datagram history[HISTORY];
static unsigned n_history;
static uint8_t seen_chal[2][16]; /* the latest two challenges the device sent */
static unsigned n_seen_chal;
static uint32_t host_seq;
static uint64_t d_guess; /* the device session, as far as the harness knows it */
static unsigned step_no;
static const char *step_name;

/* Flood accounting: host datagrams since the latest and the one-before boundary
 * (sample sent, heartbeat edge, watchdog kick), and tag checks since the latest. */
static unsigned host_rx_cur, host_rx_prev, tag_checks_cur;
static int last_was_boundary;
static uint32_t poll_wait;     /* what the last poll returned */
/* The command in force when the outputs were last set (the outputs change only at
 * set_solenoids, once per sample period): what justifies them until the next call. */
static int sol_applied;
/* JOINs after which an output stayed on until the next period (reported at exit). */
static unsigned long join_left_on;
static int trace; /* FZ_TRACE=1 in the environment: print each step (for reading a seed) */
static unsigned sol_locks;
static uint64_t sol_echo_at;

static void dump(const char *what, const uint8_t *d, size_t n)
{
    fprintf(stderr, "%s (%zu bytes):", what, n);
    for (size_t i = 0; i < n; i++)
        fprintf(stderr, " %02x", d[i]);
    fprintf(stderr, "\n");
}

static void fail(const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "device invariant broken at step %u (%s), t = %llu us: ", step_no,
            step_name, (unsigned long long)B.fb.now);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\n");
    if (B.pending || B.in.len)
        dump("last datagram delivered", B.in.data, B.in.len);
    abort();
}

/* ---- board callbacks ---- */

static event *log_event(ev_kind k)
{
    if (B.n_ev == MAX_EVENTS)
        fail("more than %u board calls in one poll", MAX_EVENTS);
    event *e = &B.ev[B.n_ev++];
    memset(e, 0, sizeof *e - sizeof e->data);
    e->kind = k;
    e->at = B.fb.now;
    return e;
}

static void set_solenoids(void *ctx, int left, int right)
{
    (void)ctx;
    event *e = log_event(EV_SOL);
    e->a = left != 0;
    e->b = right != 0;
    B.left = e->a;
    B.right = e->b;
}

static int send_cb(void *ctx, const uint8_t *d, size_t len, exo_endpoint to)
{
    (void)ctx;
    event *e = log_event(EV_SEND);
    if (len > sizeof e->data)
        fail("device sent %zu bytes, more than any packet", len);
    memcpy(e->data, d, len);
    e->len = len;
    e->ip = to.ip;
    e->port = to.port;
    return 0;
}

static long receive_cb(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from)
{
    (void)ctx;
    if (!B.pending)
        return EXO_RX_NONE;
    B.pending = 0;
    event *e = log_event(EV_RX);
    memcpy(e->data, B.in.data, B.in.len);
    e->len = B.in.len;
    e->ip = B.in.ip;
    e->port = B.in.port;
    from->ip = B.in.ip;
    from->port = B.in.port;
    if (B.in.len > cap)
        return (long)B.in.len;
    memcpy(buf, B.in.data, B.in.len);
    return (long)B.in.len;
}

static uint64_t splitmix(uint64_t *s)
{
    uint64_t z = (*s += 0x9E3779B97F4A7C15u);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9u;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBu;
    return z ^ (z >> 31);
}

static int random_cb(void *ctx, uint8_t *out, size_t n)
{
    (void)ctx;
    event *e = log_event(EV_RAND);
    for (size_t i = 0; i < n; i++)
        out[i] = (uint8_t)splitmix(&B.rng);
    e->len = n < sizeof e->data ? n : sizeof e->data;
    memcpy(e->data, out, e->len);
    return 0;
}

static void heartbeat_cb(void *ctx, int level)
{
    (void)ctx;
    log_event(EV_HB)->a = level != 0;
}

static void kick_cb(void *ctx)
{
    (void)ctx;
    log_event(EV_KICK);
}

/* ---- the model walk ---- */

typedef struct {
    uint64_t v[FZ_C_NONE + FZ_REASONS];
} counters;

/* The device's datagram counters, one slot per place a datagram can be counted. */
static void snapshot(counters *c)
{
    memset(c, 0, sizeof *c);
    c->v[FZ_C_FOREIGN] = dev.stats.foreign;
    c->v[FZ_C_FLOOD] = dev.stats.flood;
    c->v[FZ_C_UNEXPECTED] = dev.stats.unexpected;
    c->v[FZ_C_HELLO] = dev.stats.hellos;
    c->v[FZ_C_JOIN] = dev.stats.joins;
    c->v[FZ_C_COMMAND] = dev.stats.commands;
    c->v[FZ_C_REPLAY] = dev.stats.replayed;
    c->v[FZ_C_STALE] = dev.stats.stale_echo;
    for (unsigned r = 1; r < EXO_DROP_REASONS; r++) {
        const char *name = exo_drop_reason_name((exo_drop_reason)r);
        for (unsigned k = 1; k < FZ_REASONS; k++)
            if (strcmp(name, fz_reason_name((fz_reason)k)) == 0)
                c->v[FZ_C_NONE + k] += dev.stats.malformed[r];
    }
}

/* Where the device counted the step's datagram: exactly one counter moved by one. */
static int counted_where(const counters *before, const counters *after, fz_count *c,
                         fz_reason *r)
{
    int found = 0;
    for (unsigned i = 0; i < FZ_C_NONE + FZ_REASONS; i++) {
        if (i == FZ_C_NONE || i == FZ_C_MALFORMED)
            continue;
        uint64_t d = after->v[i] - before->v[i];
        if (d == 0)
            continue;
        if (d != 1 || found)
            fail("one datagram moved the device's counters by more than one");
        found = 1;
        if (i > FZ_C_NONE) {
            *c = FZ_C_MALFORMED;
            *r = (fz_reason)(i - FZ_C_NONE);
        } else {
            *c = (fz_count)i;
            *r = FZ_OK;
        }
    }
    return found;
}

static void boundary(void)
{
    if (!last_was_boundary) {
        host_rx_prev = host_rx_cur;
        host_rx_cur = 0;
        tag_checks_cur = 0;
    }
    last_was_boundary = 1;
}

/* The outputs the document allows at `now`, given the command in force (applied,
 * locks, and echo_at: the send time of the sample it echoed). */
static void check_outputs_by(int left, int right, uint64_t now, const char *when, int applied,
                             unsigned locks, uint64_t echo_at)
{
    if (!left && !right)
        return;
    if (!applied)
        fail("%s: output on (%d, %d) without an applied COMMAND of the joined session", when,
             left, right);
    if (((left && !(locks & 1u)) || (right && !(locks & 2u))))
        fail("%s: output (%d, %d) not asked by the latest applied COMMAND (locks %u)", when,
             left, right, locks);
    if (now - echo_at > FZ_FRESH_US + FZ_PERIOD_US)
        fail("%s: output on %llu us after the sample the last applied COMMAND echoed", when,
             (unsigned long long)(now - echo_at));
}

static void check_outputs(int left, int right, uint64_t now, const char *when)
{
    check_outputs_by(left, right, now, when, M.joined && M.applied, M.locks, M.echo_at);
}

static void check_sample(const event *e, const fz_pkt *p)
{
    if (!M.joined)
        fail("SAMPLE sent before any JOIN");
    if (e->ip != M.dest_ip || e->port != M.dest_port)
        fail("SAMPLE sent to %08x:%u, not the latest JOIN's source", e->ip, e->port);
    if (p->receiver != M.h)
        fail("SAMPLE names host session %016llx, not the joined %016llx",
             (unsigned long long)p->receiver, (unsigned long long)M.h);
    if (p->has_truth)
        fail("SAMPLE with the ground-truth extension from a board without truth");
    if (M.any_sample && p->seq != M.next_sample_seq)
        fail("SAMPLE seq %u, expected %u", p->seq, M.next_sample_seq);
    if (!M.any_sample && (p->seq != 0 || p->t_us != 0))
        fail("first SAMPLE has seq %u at t_us %llu, not 0 at 0", p->seq,
             (unsigned long long)p->t_us);
    if (M.any_sample && p->t_us <= M.last_t_us)
        fail("SAMPLE t_us went from %llu to %llu", (unsigned long long)M.last_t_us,
             (unsigned long long)p->t_us);
    unsigned sol = p->status & 3u;
    if (sol != ((unsigned)B.left | (unsigned)B.right << 1))
        fail("SAMPLE status says solenoids %u, the board drives %d,%d", sol, B.left, B.right);
    if ((p->status & 0x80u) && sol)
        fail("SAMPLE says WATCHDOG_RELEASED with a solenoid driven");
    if (!M.applied && !(p->status & 0x80u))
        fail("SAMPLE without WATCHDOG_RELEASED before any COMMAND of the session");
    if (p->auth_drops != M.auth_drops || p->replay_drops != M.replay_drops ||
        p->stale_drops != M.stale_drops)
        fail("SAMPLE drop counters %u/%u/%u, counted %llu/%llu/%llu", p->auth_drops,
             p->replay_drops, p->stale_drops, (unsigned long long)M.auth_drops,
             (unsigned long long)M.replay_drops, (unsigned long long)M.stale_drops);
    /* The schedule (protocol "Timing"): sample n is due at origin + t_us, never sent
     * before it; a device more than 250 ms behind rebases its origin instead. */
    uint64_t due = M.origin + p->t_us;
    if (e->at < due)
        fail("SAMPLE t_us %llu sent %llu us before it was due", (unsigned long long)p->t_us,
             (unsigned long long)(due - e->at));
    if (e->at - due > FZ_RESYNC_US) {
        M.origin = e->at - p->t_us;
        due = e->at;
    }
    M.any_sample = 1;
    M.next_sample_seq = p->seq + 1u;
    M.last_t_us = p->t_us;
    if (M.ring_n == FZ_RING) {
        memmove(M.ring, M.ring + 1, sizeof M.ring[0] * (FZ_RING - 1));
        M.ring_n--;
    }
    M.ring[M.ring_n].seq = p->seq;
    M.ring[M.ring_n].at = e->at;
    M.ring[M.ring_n].due = due;
    M.ring_n++;
    boundary();
}

/* Walk the poll's board calls in order through the model. `rx_count` is where the
 * device counted the step's datagram (if any). */
static void walk(fz_count rx_count, fz_reason rx_reason)
{
    int answer = FZ_ANSWER_NONE;
    uint32_t answer_ip = 0, answer_seq = 0;
    uint16_t answer_port = 0;
    uint64_t answer_sender = 0;
    int got_answer = 0;
    for (unsigned i = 0; i < B.n_ev; i++) {
        event *e = &B.ev[i];
        switch (e->kind) {
        case EV_RX: {
            fz_reason want_r;
            fz_pkt p;
            fz_count want = fz_model_predict(&M, e->data, e->len, e->ip, e->at, &want_r, &p);
            last_was_boundary = 0;
            if (e->ip == M.host_ip)
                host_rx_cur++;
            if (rx_count == FZ_C_FLOOD) {
                if (e->ip != M.host_ip)
                    fail("datagram from another IP counted as flood");
                if (host_rx_cur + host_rx_prev <= FZ_BUDGET)
                    fail("flood drop after only %u datagrams in this period and the one before",
                         host_rx_cur + host_rx_prev - 1u);
                break;
            }
            /* The board contract: a datagram longer than the core's buffer (one byte
             * more than the largest packet, 169 bytes) is counted as `length` unread. */
            if (e->ip == M.host_ip && e->len > 169 && rx_count == FZ_C_MALFORMED &&
                rx_reason == FZ_LENGTH) {
                want = FZ_C_MALFORMED;
                want_r = FZ_LENGTH;
            }
            if (rx_count != want || (want == FZ_C_MALFORMED && rx_reason != want_r))
                fail("datagram counted as %s, the document says %s",
                     fz_count_name(rx_count, rx_reason), fz_count_name(want, want_r));
            if (want != FZ_C_FOREIGN &&
                !(want == FZ_C_MALFORMED &&
                  (want_r == FZ_SHORT || want_r == FZ_MAGIC || want_r == FZ_LENGTH)))
                if (++tag_checks_cur > FZ_BUDGET)
                    fail("more than %u tag checks in one period", FZ_BUDGET);
            answer = fz_model_apply(&M, want, want_r, &p, e->ip, e->port, e->at);
            answer_ip = e->ip;
            answer_port = e->port;
            answer_seq = p.host_seq;
            answer_sender = p.sender;
            if (want == FZ_C_JOIN && (dev.stats.host.ip != e->ip || dev.stats.host.port != e->port))
                fail("accepted JOIN did not move the host address");
            break;
        }
        case EV_RAND:
            if (M.chal_awaiting_draw && e->len == 16) {
                memcpy(M.chal, e->data, 16);
                M.chal_known = 1;
                M.chal_awaiting_draw = 0;
            }
            break;
        case EV_SOL:
            check_outputs(e->a, e->b, e->at, "set_solenoids");
            /* Set on only while the echoed sample is at most 100 ms old: a command
             * that arrived late (held back on the path) gets a shorter life. */
            if ((e->a || e->b) && e->at - M.echo_at > FZ_FRESH_US)
                fail("set_solenoids: output on %llu us after the sample the COMMAND echoed",
                     (unsigned long long)(e->at - M.echo_at));
            sol_applied = M.joined && M.applied;
            sol_locks = M.locks;
            sol_echo_at = M.echo_at;
            /* Two-sided: inside the window the outputs are what the command says. */
            if (M.joined && M.applied && e->at - M.echo_at < FZ_FRESH_US &&
                (e->a != (int)(M.locks & 1u) || e->b != (int)((M.locks >> 1) & 1u)))
                fail("outputs (%d, %d) %llu us after the sample a COMMAND with locks %u echoed",
                     e->a, e->b, (unsigned long long)(e->at - M.echo_at), M.locks);
            break;
        case EV_HB:
            if (B.hb_known && e->a == B.hb_level)
                fail("heartbeat set to %d twice: not a toggle", e->a);
            B.hb_known = 1;
            B.hb_level = e->a;
            if (M.applied && M.stop_heartbeat && e->at - M.echo_at < FZ_FRESH_US)
                fail("heartbeat toggled while STOP_HEARTBEAT is in force");
            boundary();
            break;
        case EV_KICK:
            boundary();
            break;
        case EV_SEND: {
            fz_pkt p;
            fz_reason r = fz_wire_check(KEY, e->data, e->len, &p);
            if (r != FZ_OK) {
                dump("sent", e->data, e->len);
                fail("device sent an invalid packet (%s)", fz_reason_name(r));
            }
            if (p.type != FZ_T_VERSION) {
                if (M.d == 0)
                    M.d = p.sender;
                if (p.sender != M.d)
                    fail("device session changed from %016llx to %016llx",
                         (unsigned long long)M.d, (unsigned long long)p.sender);
                d_guess = M.d;
            }
            if (p.type == FZ_T_SAMPLE) {
                check_sample(e, &p);
            } else if (p.type == FZ_T_CHALLENGE) {
                if (answer != FZ_ANSWER_CHALLENGE || got_answer)
                    fail("CHALLENGE sent without a HELLO the document says to answer");
                got_answer = 1;
                if (e->ip != answer_ip || e->port != answer_port)
                    fail("CHALLENGE not sent to the HELLO's source");
                if (p.receiver != answer_sender || p.hello_seq != answer_seq)
                    fail("CHALLENGE does not answer the HELLO (session/seq)");
                if (p.lifetime_ms != 1000)
                    fail("CHALLENGE lifetime %u ms", p.lifetime_ms);
                if (memcmp(p.unique_id, UNIQUE_ID, 16) != 0 || memcmp(p.firmware, FIRMWARE, 16) != 0)
                    fail("CHALLENGE identity is not the configured one");
                if (!M.chal_present)
                    fail("CHALLENGE without a drawn challenge");
                if (M.chal_known && memcmp(p.challenge, M.chal, 16) != 0)
                    fail("CHALLENGE carries other bytes than the current challenge");
                if (!M.chal_known) { /* drawn in a way the harness did not see */
                    for (unsigned k = 0; k < n_seen_chal && k < 2; k++)
                        if (memcmp(seen_chal[k], p.challenge, 16) == 0)
                            fail("a redrawn challenge repeats an earlier one");
                    memcpy(M.chal, p.challenge, 16);
                    M.chal_known = 1;
                    M.chal_awaiting_draw = 0;
                }
                memcpy(seen_chal[1], seen_chal[0], 16);
                memcpy(seen_chal[0], p.challenge, 16);
                n_seen_chal++;
            } else if (p.type == FZ_T_VERSION) {
                if ((answer != FZ_ANSWER_VERSION && answer != FZ_ANSWER_VERSION_MAY) || got_answer)
                    fail("VERSION sent without an authentic datagram of another version to answer");
                got_answer = 1;
                if (e->ip != answer_ip || e->port != answer_port)
                    fail("VERSION not sent to the datagram's source");
                if (p.lowest != 3 || p.highest != 3 || p.version != 3)
                    fail("VERSION says %u..%u (byte %u), not 3..3", p.lowest, p.highest, p.version);
                M.version_sent_ever = 1;
                M.version_sent_at = e->at;
            } else {
                fail("device sent a packet of type %u", p.type);
            }
            break;
        }
        }
    }
    if (!got_answer && (answer == FZ_ANSWER_CHALLENGE || answer == FZ_ANSWER_VERSION))
        fail("no %s answered the datagram", answer == FZ_ANSWER_CHALLENGE ? "CHALLENGE" : "VERSION");
}

static void poll_once(void)
{
    counters before, after;
    int delivered = B.pending;
    uint64_t host_ip_before = dev.stats.host.ip;
    uint16_t host_port_before = dev.stats.host.port;
    snapshot(&before);
    B.n_ev = 0;
    poll_wait = exo_device_poll(&dev);
    snapshot(&after);
    if (B.pending)
        fail("the device left a datagram unread");
    fz_count c = FZ_C_NONE;
    fz_reason r = FZ_OK;
    int counted = counted_where(&before, &after, &c, &r);
    if (delivered && !counted)
        fail("a datagram was not counted anywhere");
    if (!delivered && counted)
        fail("a counter moved without a datagram");
    walk(c, r);
    if (trace && (delivered || B.left || B.right))
        fprintf(stderr, "step %3u %-22s t=%8llu us: %-12s outputs %d%d, sent %llu samples\n",
                step_no, step_name, (unsigned long long)(B.fb.now - 1000000u),
                delivered ? fz_count_name(c, r) : "-", B.left, B.right,
                (unsigned long long)dev.stats.samples_sent);
    if (c != FZ_C_JOIN && (dev.stats.host.ip != host_ip_before || dev.stats.host.port != host_port_before))
        fail("the sample destination moved without an accepted JOIN (counted as %s)",
             fz_count_name(c, r));
    /* Between two sample periods the outputs are those set at the last one, justified
     * by the command in force then (the core applies a COMMAND, and a JOIN's release,
     * from the next period on); they must still drop 100 ms + one period after it. */
    check_outputs_by(B.left, B.right, B.fb.now, "after the step", sol_applied, sol_locks,
                     sol_echo_at);
    if ((B.left || B.right) && c == FZ_C_JOIN)
        join_left_on++;
}

/* ---- the program ---- */

typedef struct {
    const uint8_t *p;
    size_t n;
} reader;

static unsigned u8(reader *r)
{
    if (r->n == 0)
        return 0;
    r->n--;
    return *r->p++;
}

static unsigned u16(reader *r) { return u8(r) | u8(r) << 8; }

static uint32_t u32(reader *r) { return (uint32_t)u16(r) | (uint32_t)u16(r) << 16; }

static uint64_t u64(reader *r) { return (uint64_t)u32(r) | (uint64_t)u32(r) << 32; }

static const uint64_t SESSIONS[3] = {0x0123456789abcdefu, 0x0fedcba987654321u, 0x5555aaaa5555aaaau};

static uint64_t pick_sender(unsigned c, reader *r)
{
    switch (c & 7u) {
    case 0:
    case 1:
    case 2: return SESSIONS[0];
    case 3: return SESSIONS[1];
    case 4: return SESSIONS[2];
    case 5: return M.h ? M.h : SESSIONS[0];
    case 6: return 0;
    default: return u64(r);
    }
}

static uint64_t pick_receiver(unsigned c, reader *r)
{
    switch (c & 3u) {
    case 0:
    case 1: return d_guess;
    case 2: return (c & 4u) ? 0 : d_guess + 1u;
    default: return u64(r);
    }
}

static uint32_t pick_seq(unsigned c, reader *r)
{
    switch (c & 7u) {
    case 0:
    case 1:
    case 2: return ++host_seq;
    case 3: return host_seq;
    case 4: return host_seq - 1u - (u8(r) & 15u);
    case 5: return M.last_seq + 0x80000000u;
    case 6: return M.last_seq + 0x7FFFFFFFu;
    default: return u32(r);
    }
}

static uint32_t pick_echo(unsigned c, reader *r)
{
    uint32_t newest = M.any_sample ? M.next_sample_seq - 1u : 0u;
    switch (c & 3u) {
    case 0:
    case 1: return newest - (u8(r) & 3u);
    case 2: return newest - (u8(r) & 31u);
    default: return u32(r);
    }
}

static void pick_challenge(unsigned c, reader *r, uint8_t out[16])
{
    switch (c & 3u) {
    case 0:
    case 1: memcpy(out, seen_chal[0], 16); break;
    case 2: memcpy(out, seen_chal[1], 16); break;
    default:
        for (unsigned i = 0; i < 16; i++)
            out[i] = (uint8_t)u8(r);
    }
}

static void remember(void)
{
    history[n_history % HISTORY] = B.in;
    n_history++;
}

static void deliver(const uint8_t *d, size_t len, uint32_t ip, uint16_t port)
{
    memcpy(B.in.data, d, len);
    B.in.len = len;
    B.in.ip = ip;
    B.in.port = port;
    B.pending = 1;
    remember();
    poll_once();
}

/* Build the packet a step names into `buf`. */
static size_t build(unsigned kind, reader *r, uint8_t *buf)
{
    unsigned a = u8(r), b = u8(r);
    uint64_t sender = pick_sender(a, r);
    switch (kind % 3u) {
    case 0: {
        uint64_t receiver = (a & 0x80u) ? pick_receiver(b, r) : 0;
        return fz_build_hello(KEY, buf, pick_seq(a >> 3, r), sender, receiver);
    }
    case 1: {
        uint8_t ch[16];
        pick_challenge(b >> 2, r, ch);
        return fz_build_join(KEY, buf, pick_seq(a >> 3, r), ch, sender, pick_receiver(b, r));
    }
    default: {
        unsigned c = u8(r);
        uint32_t seq = pick_seq(a >> 3, r);
        uint32_t echo = pick_echo(b >> 2, r);
        return fz_build_command(KEY, buf, seq, echo, c & 3u, (c & 4u) != 0, sender,
                                pick_receiver(b, r));
    }
    }
}

/* Simulated time a program may spend polling on time (each period costs a sample
 * and its tags); beyond it the clock only jumps, so that an input runs in
 * milliseconds. */
#define POLLED_BUDGET_US 4000000u
static uint64_t polled_us;

static void advance(uint64_t dt, int stalled)
{
    uint64_t target = B.fb.now + dt;
    if (!stalled && polled_us + dt > POLLED_BUDGET_US)
        stalled = 1;
    if (!stalled)
        polled_us += dt;
    if (stalled) {
        B.fb.now = target;
        poll_once();
        return;
    }
    while (B.fb.now < target) {
        /* A port on time: sleep for what poll returned (at least 1 us). */
        uint64_t wait = poll_wait ? poll_wait : 1u;
        B.fb.now = B.fb.now + wait < target ? B.fb.now + wait : target;
        poll_once();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static int ready;
    if (!ready) {
        for (unsigned i = 0; i < 32; i++)
            KEY[i] = (uint8_t)i;
        trace = getenv("FZ_TRACE") != NULL;
        ready = 1;
    }
    reader rd = {data, size};
    memset(&B, 0, sizeof B);
    fake_init(&B.fb);
    B.rng = 0x243F6A8885A308D3u ^ u8(&rd);
    exo_board board_if = fake_interface(&B.fb, 1);
    board_if.ctx = &B;
    board_if.set_solenoids = set_solenoids;
    board_if.send = send_cb;
    board_if.receive = receive_cb;
    board_if.random_bytes = random_cb;
    board_if.heartbeat = heartbeat_cb;
    board_if.kick_watchdog = kick_cb;
    board_if.truth = NULL;

    exo_config cfg;
    memset(&cfg, 0, sizeof cfg);
    memcpy(cfg.key, KEY, sizeof KEY);
    cfg.host_ip = HOST_IP;
    cfg.bus = EXO_BUS_CHIP_SELECTS;
    memcpy(cfg.unique_id, UNIQUE_ID, 16);
    memcpy(cfg.firmware, FIRMWARE, 16);

    fz_model_init(&M, KEY, HOST_IP, UNIQUE_ID, (const uint8_t *)FIRMWARE);
    n_history = 0;
    n_seen_chal = 0;
    memset(seen_chal, 0, sizeof seen_chal);
    host_seq = 0;
    d_guess = 0;
    step_no = 0;
    step_name = "init";
    host_rx_cur = host_rx_prev = tag_checks_cur = 0;
    polled_us = 0;
    last_was_boundary = 0;

    B.n_ev = 0;
    if (exo_device_init(&dev, &board_if, &cfg) != 0)
        fail("init refused a valid configuration");
    /* The device session is the first random draw's first 8 bytes, if the core does it
     * that way; it is only a guess for building datagrams until the device sends. */
    for (unsigned i = 0; i < B.n_ev; i++)
        if (B.ev[i].kind == EV_RAND && B.ev[i].len >= 8) {
            d_guess = fz_le64(B.ev[i].data);
            break;
        }
    sol_applied = 0;
    walk(FZ_C_NONE, FZ_OK);
    check_outputs(B.left, B.right, B.fb.now, "after init");

    uint8_t buf[FZ_MAX_DATAGRAM];
    while (rd.n > 0 && step_no < MAX_STEPS) {
        step_no++;
        unsigned op = u8(&rd);
        switch ((op & 0x3Fu) % 12u) { /* bits 6-7: the step's options */
        case 0:
        case 1: { /* the clock moves */
            unsigned v = u16(&rd);
            static const uint64_t unit[4] = {1, 10, 100, 1000};
            step_name = (op & 0x80u) ? "advance (stalled port)" : "advance";
            advance((uint64_t)(v & 0x3FFFu) * unit[v >> 14], (op & 0x80u) != 0);
            break;
        }
        case 2:
            step_name = "HELLO";
            deliver(buf, build(0, &rd, buf), HOST_IP, (op & 0x80u) ? (uint16_t)u16(&rd) : HOST_PORT);
            break;
        case 3:
            step_name = "JOIN";
            deliver(buf, build(1, &rd, buf), HOST_IP, (op & 0x80u) ? (uint16_t)u16(&rd) : HOST_PORT);
            break;
        case 4:
        case 5:
            step_name = "COMMAND";
            deliver(buf, build(2, &rd, buf), HOST_IP, (op & 0x80u) ? (uint16_t)u16(&rd) : HOST_PORT);
            break;
        case 6: { /* replay an earlier datagram, from its source or another port */
            step_name = "replay";
            if (n_history == 0)
                break;
            unsigned back = u8(&rd) % (n_history < HISTORY ? n_history : HISTORY);
            datagram old = history[(n_history - 1u - back) % HISTORY];
            deliver(old.data, old.len, old.ip, (op & 0x80u) ? (uint16_t)(old.port + 1u) : old.port);
            break;
        }
        case 7: { /* a foreign source: an earlier datagram or a fresh one */
            step_name = "foreign";
            if (n_history > 0 && (op & 0x80u)) {
                datagram old = history[(n_history - 1u) % HISTORY];
                deliver(old.data, old.len, OTHER_IP, old.port);
            } else {
                deliver(buf, build(u8(&rd), &rd, buf), (op & 0x40u) ? u32(&rd) | 1u : OTHER_IP,
                        HOST_PORT);
            }
            break;
        }
        case 8:
            step_name = "empty";
            deliver(buf, 0, (op & 0x80u) ? OTHER_IP : HOST_IP, HOST_PORT);
            break;
        case 9: { /* raw bytes, re-authenticated or not */
            step_name = "raw";
            size_t len = u8(&rd) % 177u; /* up to a few bytes over the largest packet */
            for (size_t i = 0; i < len; i++)
                buf[i] = (uint8_t)u8(&rd);
            if ((op & 0x80u) && len >= 44)
                fz_reauth(KEY, buf, len);
            deliver(buf, len, HOST_IP, HOST_PORT);
            break;
        }
        case 10: { /* a built packet with bytes changed, re-authenticated or not */
            step_name = "mutated";
            size_t len = build(u8(&rd), &rd, buf);
            unsigned flips = 1u + u8(&rd) % 4u;
            for (unsigned k = 0; k < flips; k++) {
                unsigned at = u8(&rd) % (unsigned)len;
                buf[at] = (uint8_t)(buf[at] ^ (1u + u8(&rd) % 255u));
            }
            if (op & 0x80u)
                fz_reauth(KEY, buf, len);
            deliver(buf, len, HOST_IP, HOST_PORT);
            break;
        }
        default: { /* another protocol version, authentic (a VERSION answer is due) */
            step_name = "other version";
            size_t len = build(u8(&rd), &rd, buf);
            buf[2] = (uint8_t)(op & 0x80u ? u8(&rd) : 2u);
            fz_reauth(KEY, buf, len);
            deliver(buf, len, HOST_IP, HOST_PORT);
            break;
        }
        }
    }
    exo_device_stop(&dev);
    return 0;
}
