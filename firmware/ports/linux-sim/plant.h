/*
 * plant.h - what the linux-sim board's encoders and mechanism show: the simulated
 * wearer (the Python SimulatedExoskeleton, a child process spoken to over pipes, see
 * controller/sim/plant_bridge.py) or a recorded counts file replayed without Python.
 */
#ifndef PLANT_H
#define PLANT_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "exo_board.h"

/* Record layouts of controller/sim/plant_bridge.py (little-endian, no padding). */
#define PLANT_READY "EXOPLNT1"
#define PLANT_READY_BYTES 8
#define PLANT_COMMAND_BYTES 4
#define PLANT_REPLY_BYTES 92
#define PLANT_REPLY_FINISHED 0x01u

typedef struct {
    uint16_t counts[4];  /* left output, left cam, right output, right cam */
    int fault[4];        /* 1: that encoder has no usable reading this period */
    uint32_t status;     /* LOCKED_*, HARD_STOP_*, SUPPLY_FAULT */
    int has_truth;
    exo_truth truth;
    int finished;        /* the script (or file) has ended with this period */
} plant_reading;

typedef struct {
    /* Python bridge */
    pid_t pid;
    int to_child;
    int from_child;
    /* Counts file */
    uint16_t *rows;      /* 4 counts per row */
    uint8_t *row_fault;  /* 4 flags per row */
    size_t n_rows;
    size_t next_row;
    int loop;
    uint64_t steps;
} plant;

/* Start `python -m controller.sim.plant_bridge` and wait (up to `ready_timeout_ms`)
 * for it to be ready. `repo_root` (may be NULL) goes first on PYTHONPATH. Returns 0,
 * or -1 with a message in `err`. */
int plant_start_python(plant *p, const char *python, const char *repo_root, long seed,
                       const char *script, double precompression_pct, int loop,
                       int ready_timeout_ms, char *err, size_t errlen);

/* Load a counts CSV: a header naming count_left_output, count_left_cam,
 * count_right_output and count_right_cam (the tick CSV of a trial or of `exostudy
 * replay`) or left_output, left_cam, right_output, right_cam; other columns are
 * ignored. A cell that is empty or not a count in 0..16383 is a faulty reading. */
int plant_open_counts(plant *p, const char *path, int loop, char *err, size_t errlen);

/* Advance one sample period with these solenoids energised. Returns 0, or -1 if the
 * plant is gone (the bridge died or answered nonsense; a message went to stderr). */
int plant_step(plant *p, int left, int right, plant_reading *out);

/* Stop the bridge (end of input, then SIGTERM if it lingers) or free the file. */
void plant_close(plant *p);

#endif /* PLANT_H */
