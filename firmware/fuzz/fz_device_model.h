/*
 * fz_device_model.h - the device's rules (docs/device-protocol.md, version 3, "The
 * device's rules" and "Safety rules"), written again from the document for the
 * state-machine harness. It never calls the core: it reads the datagrams the harness
 * delivers and the packets, outputs and random draws the core produces through the
 * board, and says what the document allows.
 */
#ifndef FZ_DEVICE_MODEL_H
#define FZ_DEVICE_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "fz_wire_model.h"

#define FZ_MS 1000u
#define FZ_PERIOD_US 10000u
#define FZ_FRESH_US (100u * FZ_MS)     /* freshness and watchdog window */
#define FZ_LIFETIME_US (1000u * FZ_MS) /* challenge lifetime */
#define FZ_REDRAW_US (500u * FZ_MS)    /* a HELLO redraws an older challenge */
#define FZ_VERSION_GAP_US (1000u * FZ_MS)
#define FZ_BUDGET 8u
#define FZ_RESYNC_US (250u * FZ_MS) /* further behind: the schedule is rebased */
#define FZ_RING 16u

/* Where a datagram is counted (the device's counters). */
typedef enum {
    FZ_C_FOREIGN = 0,
    FZ_C_FLOOD,
    FZ_C_MALFORMED, /* + the fz_reason */
    FZ_C_UNEXPECTED,
    FZ_C_HELLO,
    FZ_C_JOIN,
    FZ_C_COMMAND,
    FZ_C_REPLAY,
    FZ_C_STALE,
    FZ_C_NONE
} fz_count;

const char *fz_count_name(fz_count c, fz_reason r);

typedef struct {
    uint32_t seq;
    uint64_t at;  /* sent (freshness is judged by it) */
    uint64_t due; /* its scheduled time, origin + t_us (<= at): the watchdog counts from it */
} fz_sent_sample;

typedef struct {
    uint8_t key[32];
    uint32_t host_ip;
    uint8_t unique_id[16];
    uint8_t firmware[16];

    uint64_t d; /* device session (0 until the device first sends) */

    int joined;           /* a JOIN was accepted this boot */
    uint64_t h;           /* host session */
    uint32_t last_seq;    /* last applied host_seq (JOIN or COMMAND) */
    uint32_t dest_ip;     /* where samples go */
    uint16_t dest_port;

    int chal_present, chal_known, chal_spent, chal_awaiting_draw;
    uint8_t chal[16];
    uint64_t chal_drawn_at;

    int version_sent_ever;
    uint64_t version_sent_at;

    fz_sent_sample ring[FZ_RING]; /* samples sent since the last JOIN, newest at ring_n-1 */
    unsigned ring_n;
    int stream_started;
    uint64_t origin;      /* the schedule's origin: sample n is due at origin + t_us */
    uint32_t next_sample_seq;
    uint64_t last_t_us;
    int any_sample;

    int applied;          /* a COMMAND applied since the last JOIN */
    unsigned locks;
    int stop_heartbeat;
    uint64_t echo_at;     /* due time of the sample it echoed: the outputs it asks for
                             may stay on until echo_at + 100 ms (+ one period), however
                             late it arrived */

    uint64_t auth_drops, replay_drops, stale_drops; /* what SAMPLEs must report */
} fz_model;

void fz_model_init(fz_model *m, const uint8_t key[32], uint32_t host_ip,
                   const uint8_t unique_id[16], const uint8_t firmware[16]);

/* What the document says happens to a datagram received at `now`: where it is
 * counted (and the reason if malformed), before the authentication budget. */
fz_count fz_model_predict(const fz_model *m, const uint8_t *d, size_t n, uint32_t ip,
                          uint64_t now, fz_reason *reason, fz_pkt *pkt);

/* What the device must send in answer to a datagram. */
#define FZ_ANSWER_NONE 0
#define FZ_ANSWER_CHALLENGE 1
#define FZ_ANSWER_VERSION 2       /* must answer with VERSION */
#define FZ_ANSWER_VERSION_MAY 3   /* exactly one second after the last: either */

/* Apply a datagram's effect given where the device counted it (already checked to be
 * what the model allows) and say what must answer it. */
int fz_model_apply(fz_model *m, fz_count c, fz_reason r, const fz_pkt *pkt, uint32_t ip,
                   uint16_t port, uint64_t now);

#endif /* FZ_DEVICE_MODEL_H */
