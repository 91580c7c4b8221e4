/*
 * stats.h - the run's statistics as the Python reference device prints them: one JSON
 * line on exit with the same keys (controller/sim/device_server.py, ServerStats), so a
 * test or benchmark reads either device the same way. The core keeps its latest
 * lateness and round-trip values in short rings; they are copied out after every poll
 * so the percentiles cover the run (up to the last hour, as in Python).
 */
#ifndef LINUX_SIM_STATS_H
#define LINUX_SIM_STATS_H

#include <stdint.h>
#include <stdio.h>

#include "board.h"
#include "exo_device.h"

#define LINUX_SIM_KEEP 360000u /* values kept for percentiles: an hour at 100 Hz */

typedef struct {
    uint32_t *values; /* ring of LINUX_SIM_KEEP */
    uint64_t n;       /* values ever added */
    uint64_t copied;  /* of the core's ring: values already copied */
} linux_sim_series;

typedef struct {
    const linux_sim_board *board;
    linux_sim_series lateness;
    linux_sim_series rtt;
} linux_sim_stats;

/* 0, or -1 if the memory for the series is not available (then no percentiles). */
int linux_sim_stats_init(linux_sim_stats *s, const linux_sim_board *board);
void linux_sim_stats_after_poll(linux_sim_stats *s, const exo_device *dev);
void linux_sim_stats_print(linux_sim_stats *s, const exo_device *dev, FILE *out);

#endif /* LINUX_SIM_STATS_H */
