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
#define EXO_RTT_RING 1024u    /* send times kept for matching echoed sample numbers */
#define EXO_STATS_RING 1024u  /* latest lateness and round-trip values kept */
#define EXO_RX_PER_POLL 64u   /* datagrams handled per poll at most (a flood cannot starve the sample) */

/* What happened since init: the counters of the reference device's ServerStats, so a
 * port can print the same summary. Counters are 64-bit and never wrap in practice.
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
    uint64_t commands;       /* valid commands applied */
    uint64_t stale_commands; /* valid, but host_seq not after the last applied one */
    uint64_t hellos;
    uint64_t foreign;    /* datagrams from any IP but the configured host */
    uint64_t unexpected; /* valid packets of a type a host never sends (SAMPLE) */
    uint64_t malformed[EXO_DROP_REASONS]; /* by exo_drop_reason; [EXO_DROP_AUTH] is
                                             auth_failures, [EXO_DROP_VERSION]
                                             unknown_version; [0] stays 0 */
    uint64_t replayed; /* authentic, but seen before, from a replaced host session, or
                          a COMMAND addressed to an earlier boot of this device */
    uint64_t watchdog_releases; /* transitions from commanded to released */
    uint64_t host_changes;      /* the host's port changed after it was first learned */
    uint64_t resyncs;           /* schedule rebased after a stall */
    uint64_t send_errors;       /* sample not encodable or board send failed */
    uint64_t receive_errors;    /* board receive returned -1 (not in the Python summary) */
    int host_known;
    exo_endpoint host;     /* learned host address (valid if host_known) */
    uint64_t streaming_us; /* since the stream started (schedule origin, as Python) */
} exo_stats;

typedef struct exo_device_s {
    exo_board board; /* a copy: the port's struct may be temporary */
    uint32_t host_ip;
    exo_bus_layout bus;
    uint32_t period_us;   /* the configured sample period */
    uint32_t rate_factor; /* fault probe: each period sent as this many samples */
    exo_hmac_key key;     /* the link key, absorbed (the raw key is not kept) */
    uint64_t session;     /* this boot's session, never 0 */
    int running;          /* init succeeded and stop was not called; else poll does
                             nothing (a zeroed, never initialised device is inert too) */

    exo_peer_sessions host_sessions;
    int have_last_host_seq; /* for stale COMMANDs; reset when the host (re)starts */
    uint32_t last_host_seq;
    unsigned locks; /* EXO_LOCK_* of the latest applied COMMAND */
    exo_watchdog watchdog;
    exo_as5048a encoders;

    int streaming;      /* the host is known; samples are due */
    uint64_t start_us;  /* schedule origin: sample k is due at start + offset(k) */
    uint64_t k;         /* next sample's index */
    uint64_t idle_due_us; /* before streaming: next hardware-watchdog kick */

    uint32_t sent_seq[EXO_RTT_RING]; /* round trip: seq and send time per ring slot */
    uint64_t sent_at_us[EXO_RTT_RING];
    uint8_t sent_valid[EXO_RTT_RING / 8u]; /* one round trip per sample */

    uint8_t rx[EXO_MAX_PACKET + 1u]; /* one byte more than any valid packet */
    uint8_t tx[EXO_MAX_PACKET];

    exo_stats stats;
} exo_device;

#endif /* EXO_CORE_TYPES_H */
