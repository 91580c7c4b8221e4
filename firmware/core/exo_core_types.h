/*
 * exo_core_types.h - the device core's state, as plain structs so that a port can
 * allocate an `exo_device` statically (no malloc anywhere). Included by exo_device.h;
 * include that header, not this one.
 *
 * A port reads `dev.stats` (for its log or JSON summary) and nothing else; every other
 * field belongs to the core and may change between versions.
 */
#ifndef EXO_CORE_TYPES_H
#define EXO_CORE_TYPES_H

#ifndef EXO_DEVICE_H
#error "include exo_device.h, not exo_core_types.h"
#endif

#include <stdint.h>

#include "as5048a.h"
#include "exo_board.h"
#include "hmac.h"
#include "session.h"
#include "watchdog.h"
#include "wire.h"

#define EXO_LATE_US 2000u     /* sent more than this after its due time: late */
#define EXO_RESYNC_US 250000u /* further behind than this: rebase the schedule, no burst */
#define EXO_STATS_RING 1024u  /* latest lateness and round-trip values kept */
#define EXO_RX_PER_POLL 64u   /* datagrams handled per poll at most (a flood cannot starve the sample) */
#define EXO_AUTH_BUDGET 8u    /* host-IP datagrams read per sample period (idle period
                                 before streaming); the rest: flood, unread */
#define EXO_VERSION_INTERVAL_US 1000000u /* at most one VERSION answer per second */

/* What happened since init: the counters of the reference device's ServerStats, so a
 * port can print the same summary. Counters are 64-bit and never wrap in practice.
 * Every datagram the board hands over is counted exactly once: as foreign, flood,
 * malformed[reason], unexpected, replayed, stale_echo, or as a hello, join or
 * command (the sends are counted besides).
 *
 * Percentiles: the core keeps the latest EXO_STATS_RING lateness and round-trip
 * values in rings. `*_n` counts every value ever written; value j (0-based, j < n)
 * sits at index j % EXO_STATS_RING while j >= n - EXO_STATS_RING. A port that wants
 * percentiles over a whole run (as the Python device keeps an hour) copies the new
 * values out at least every EXO_STATS_RING samples, i.e. every poll is plenty. */
typedef struct {
    uint64_t samples_sent; /* samples built and handed to send (also if send failed) */
    uint64_t late;         /* of those, sent more than EXO_LATE_US after due */
    uint32_t lateness_max_us;
    uint64_t lateness_n;
    uint32_t lateness_us[EXO_STATS_RING]; /* send time minus due time, microseconds */
    uint64_t rtt_n;
    uint32_t rtt_max_us;
    uint32_t rtt_us[EXO_STATS_RING]; /* sample sent -> COMMAND echoing it received */
    uint64_t commands;   /* valid commands applied */
    uint64_t hellos;     /* authentic HELLOs within the budget (each one answered) */
    uint64_t joins;      /* JOINs accepted */
    uint64_t challenges; /* CHALLENGEs sent */
    uint64_t versions_sent;     /* VERSION answers sent */
    uint64_t foreign;    /* datagrams from any IP but the configured host */
    uint64_t flood;      /* from the host IP, over the period's tag-check budget: unread */
    uint64_t unexpected; /* valid packets of a type a host never sends */
    uint64_t malformed[EXO_DROP_REASONS]; /* by exo_drop_reason; [EXO_DROP_AUTH] is
                                             auth_failures, [EXO_DROP_VERSION]
                                             unknown_version; [0] stays 0 */
    uint64_t replayed;   /* authentic JOIN/COMMAND not of this boot or the current host
                            session, not advancing host_seq, or answering a spent,
                            expired or unknown challenge (SAMPLE cmd_replay_drops) */
    uint64_t stale_echo; /* COMMANDs of the current session echoing a sample older than
                            100 ms or unknown (SAMPLE cmd_stale_drops) */
    uint64_t watchdog_releases; /* transitions from commanded to released */
    uint64_t host_changes;      /* a JOIN moved the host's address after the first */
    uint64_t resyncs;           /* schedule rebased after a stall */
    uint64_t send_errors;       /* a packet not encodable or board send failed */
    uint64_t receive_errors;    /* board receive returned -1 (not in the Python summary) */
    uint64_t random_errors;     /* no entropy for a challenge (the HELLO goes unanswered) */
    uint64_t heartbeat_edges;   /* heartbeat output toggles */
    int host_known;
    exo_endpoint host;     /* where samples go: the latest JOIN's source (if host_known) */
    uint64_t streaming_us; /* since the stream started (schedule origin, as Python) */
} exo_stats;

typedef struct exo_device_s {
    exo_board board; /* a copy: the port's struct may be temporary */
    uint32_t host_ip;
    exo_bus_layout bus;
    uint32_t period_us;   /* the configured sample period */
    uint32_t rate_factor; /* fault probe: each period sent as this many samples */
    exo_hmac_key key;     /* the link key, absorbed (the raw key is not kept) */
    uint64_t session;     /* this boot's session D, never 0 */
    int running;          /* init succeeded and stop was not called; else poll does
                             nothing (a zeroed, never initialised device is inert too) */
    uint8_t unique_id[EXO_UNIQUE_ID_BYTES];
    uint8_t firmware[EXO_FIRMWARE_BYTES];

    exo_host host;           /* H, its last host_seq and address */
    exo_challenge challenge; /* the one challenge */
    int version_sent;        /* a VERSION has gone out (last_version_us valid) */
    uint64_t last_version_us;
    unsigned auth_checks;    /* datagrams from the host IP this period (budget
                                EXO_AUTH_BUDGET: the most that reach the tag check) */

    unsigned locks;     /* EXO_LOCK_* of the latest applied COMMAND */
    int stop_heartbeat; /* the latest applied COMMAND had STOP_HEARTBEAT */
    int heartbeat_level;
    exo_watchdog watchdog;
    exo_as5048a encoders;

    int streaming;        /* the first JOIN was accepted; samples are due */
    uint64_t start_us;    /* schedule origin: sample k is due at start + offset(k) */
    uint64_t k;           /* next sample's index (seq is its low 32 bits) */
    uint64_t idle_due_us; /* before streaming: next idle period (watchdog kick, heartbeat) */

    exo_sent_ring sent; /* send times of the last 16 samples (cleared at JOIN) */

    uint8_t rx[EXO_MAX_PACKET + 1u]; /* one byte more than any valid packet */
    uint8_t tx[EXO_MAX_PACKET];

    exo_stats stats;
} exo_device;

#endif /* EXO_CORE_TYPES_H */
