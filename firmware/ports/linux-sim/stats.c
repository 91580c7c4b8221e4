/*
 * stats.c - the JSON summary of a run (see stats.h).
 */
#include "stats.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int linux_sim_stats_init(linux_sim_stats *s, const linux_sim_board *board) {
    memset(s, 0, sizeof *s);
    s->board = board;
    s->lateness.values = malloc(LINUX_SIM_KEEP * sizeof(uint32_t));
    s->rtt.values = malloc(LINUX_SIM_KEEP * sizeof(uint32_t));
    return s->lateness.values != NULL && s->rtt.values != NULL ? 0 : -1;
}

/* Copy what the core added to its ring since the last call (at most a ring's worth:
 * older values were overwritten, which a poll per sample never lets happen). */
static void copy_ring(linux_sim_series *s, const uint32_t *ring, uint64_t ring_n) {
    uint64_t from = s->copied;
    if (ring_n - from > EXO_STATS_RING)
        from = ring_n - EXO_STATS_RING;
    for (uint64_t j = from; j < ring_n; j++) {
        if (s->values != NULL)
            s->values[s->n % LINUX_SIM_KEEP] = ring[j % EXO_STATS_RING];
        s->n++;
    }
    s->copied = ring_n;
}

void linux_sim_stats_after_poll(linux_sim_stats *s, const exo_device *dev) {
    copy_ring(&s->lateness, dev->stats.lateness_us, dev->stats.lateness_n);
    copy_ring(&s->rtt, dev->stats.rtt_us, dev->stats.rtt_n);
}

static int cmp_u32(const void *a, const void *b) {
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* Percentile q of the kept values, in ms, by the Python device's rule: the value at
 * index ceil(q/100 * n) - 1 of the sorted values. NaN if there are none. */
static double percentile_ms(const linux_sim_series *s, double q) {
    uint64_t kept = s->n < LINUX_SIM_KEEP ? s->n : LINUX_SIM_KEEP;
    if (kept == 0 || s->values == NULL)
        return NAN;
    uint32_t *sorted = malloc(kept * sizeof *sorted);
    if (sorted == NULL)
        return NAN;
    memcpy(sorted, s->values, kept * sizeof *sorted);
    qsort(sorted, kept, sizeof *sorted, cmp_u32);
    double rank = ceil(q / 100.0 * (double)kept) - 1.0;
    size_t i = rank < 0 ? 0 : (size_t)rank;
    if (i > kept - 1)
        i = (size_t)(kept - 1);
    double v = sorted[i] / 1000.0;
    free(sorted);
    return v;
}

/* A float as Python's json.dumps writes it: the shortest digits that read back as the
 * same double, ".0" on a whole number, NaN as NaN. */
static void put_float(FILE *out, const char *key, double v) {
    if (isnan(v)) {
        fprintf(out, "\"%s\": NaN", key);
        return;
    }
    char text[40];
    for (int digits = 1; digits <= 17; digits++) {
        snprintf(text, sizeof text, "%.*g", digits, v);
        if (strtod(text, NULL) == v)
            break;
    }
    int plain = strpbrk(text, ".eni") == NULL; /* no point, exponent, inf or nan */
    fprintf(out, "\"%s\": %s%s", key, text, plain ? ".0" : "");
}

void linux_sim_stats_print(linux_sim_stats *s, const exo_device *dev, FILE *out) {
    const exo_stats *st = &dev->stats;
    linux_sim_stats_after_poll(s, dev);
    unsigned long long sent = (unsigned long long)st->samples_sent;
    fprintf(out, "{\"samples_sent\": %llu, \"late\": %llu, ", sent,
            (unsigned long long)st->late);
    put_float(out, "late_fraction", sent ? (double)st->late / (double)sent : 0.0);
    fputs(", ", out);
    put_float(out, "lateness_p50_ms", percentile_ms(&s->lateness, 50));
    fputs(", ", out);
    put_float(out, "lateness_p99_ms", percentile_ms(&s->lateness, 99));
    fputs(", ", out);
    put_float(out, "lateness_max_ms", st->lateness_max_us / 1000.0);
    fprintf(out, ", \"rtt_n\": %llu, ",
            (unsigned long long)(s->rtt.n < LINUX_SIM_KEEP ? s->rtt.n : LINUX_SIM_KEEP));
    put_float(out, "rtt_p50_ms", percentile_ms(&s->rtt, 50));
    fputs(", ", out);
    put_float(out, "rtt_p99_ms", percentile_ms(&s->rtt, 99));
    fputs(", ", out);
    put_float(out, "rtt_max_ms", st->rtt_n ? st->rtt_max_us / 1000.0 : NAN);
#define U(x) ((unsigned long long)(x))
    fprintf(out, ", \"commands\": %llu, \"stale_commands\": %llu, \"hellos\": %llu, "
                 "\"challenges\": %llu, \"joins\": %llu, "
                 "\"versions_sent\": %llu, \"foreign\": %llu, \"flood\": %llu, "
                 "\"unexpected\": %llu, \"malformed\": {",
            U(st->commands), U(st->stale_echo), U(st->hellos), U(st->challenges),
            U(st->joins), U(st->versions_sent), U(st->foreign),
            U(st->flood), U(st->unexpected));
    int first = 1;
    for (int r = 1; r < EXO_DROP_REASONS; r++) {
        if (st->malformed[r] == 0)
            continue;
        fprintf(out, "%s\"%s\": %llu", first ? "" : ", ",
                exo_drop_reason_name((exo_drop_reason)r), U(st->malformed[r]));
        first = 0;
    }
    /* Every drop by reason, the state drops included, under the names the protocol
     * document and the Python device share (non-zero ones only, as a Counter). */
    fputs("}, \"drops\": {", out);
    first = 1;
    for (int r = 1; r < EXO_DROP_REASONS; r++) {
        if (st->malformed[r] == 0)
            continue;
        fprintf(out, "%s\"%s\": %llu", first ? "" : ", ",
                exo_drop_reason_name((exo_drop_reason)r), U(st->malformed[r]));
        first = 0;
    }
    const struct {
        const char *name;
        uint64_t n;
    } state[5] = {{"foreign", st->foreign},     {"flood", st->flood},
                  {"replay", st->replayed},     {"stale_echo", st->stale_echo},
                  {"unexpected", st->unexpected}};
    for (int i = 0; i < 5; i++) {
        if (state[i].n == 0)
            continue;
        fprintf(out, "%s\"%s\": %llu", first ? "" : ", ", state[i].name, U(state[i].n));
        first = 0;
    }
    char host[32] = "";
    if (st->host_known)
        snprintf(host, sizeof host, "%u.%u.%u.%u:%u", (unsigned)(st->host.ip >> 24) & 255u,
                 (unsigned)(st->host.ip >> 16) & 255u, (unsigned)(st->host.ip >> 8) & 255u,
                 (unsigned)st->host.ip & 255u, (unsigned)st->host.port);
    fprintf(out, "}, \"auth_failures\": %llu, \"replayed\": %llu, \"unknown_version\": %llu, "
                 "\"watchdog_releases\": %llu, \"driver_cutoffs\": %llu, "
                 "\"host_changes\": %llu, \"resyncs\": %llu, \"send_errors\": %llu, "
                 "\"host\": \"%s\", ",
            U(st->malformed[EXO_DROP_AUTH]), U(st->replayed), U(st->malformed[EXO_DROP_VERSION]),
            U(st->watchdog_releases), U(s->board->driver_cutoffs), U(st->host_changes),
            U(st->resyncs), U(st->send_errors), host);
#undef U
    put_float(out, "streaming_s", st->host_known ? (double)st->streaming_us / 1e6 : 0.0);
    fprintf(out, ", \"implementation\": \"c\", \"wearer_periods\": %llu, ",
            (unsigned long long)s->board->periods);
    put_float(out, "wearer_step_max_ms", (double)s->board->step_max_us / 1000.0);
    fprintf(out, ", \"wearer_slow_steps\": %llu, \"spi_frames\": %llu}\n",
            (unsigned long long)s->board->slow_steps, (unsigned long long)s->board->spi_frames);
    free(s->lateness.values);
    free(s->rtt.values);
    s->lateness.values = s->rtt.values = NULL;
}
