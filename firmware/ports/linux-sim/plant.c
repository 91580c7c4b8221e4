/*
 * plant.c - the simulated wearer behind the linux-sim board (see plant.h).
 */
#include "plant.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* How long one period's answer may take before the bridge counts as hung: far above
 * a step (tens of microseconds) and a scheduling delay on a loaded machine. */
#define STEP_TIMEOUT_MS 2000

static uint64_t ms_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

/* Read exactly `n` bytes within `timeout_ms`; 0, or -1 (end of input, error, timeout). */
static int read_full(int fd, uint8_t *buf, size_t n, int timeout_ms) {
    uint64_t deadline = ms_now() + (uint64_t)timeout_ms;
    size_t got = 0;
    while (got < n) {
        uint64_t now = ms_now();
        if (now >= deadline)
            return -1;
        struct pollfd pfd = {.fd = fd, .events = POLLIN};
        int r = poll(&pfd, 1, (int)(deadline - now));
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            return -1;
        ssize_t k = read(fd, buf + got, n - got);
        if (k < 0 && (errno == EINTR || errno == EAGAIN))
            continue;
        if (k <= 0)
            return -1;
        got += (size_t)k;
    }
    return 0;
}

static int write_full(int fd, const uint8_t *buf, size_t n) {
    size_t put = 0;
    while (put < n) {
        ssize_t k = write(fd, buf + put, n - put);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return -1;
        put += (size_t)k;
    }
    return 0;
}

static void plant_init(plant *p) {
    memset(p, 0, sizeof *p);
    p->pid = -1;
    p->to_child = -1;
    p->from_child = -1;
}

int plant_start_python(plant *p, const char *python, const char *repo_root, long seed,
                       const char *script, double precompression_pct, int loop,
                       int ready_timeout_ms, char *err, size_t errlen) {
    plant_init(p);
    int cmd[2], reply[2];
    if (pipe2(cmd, O_CLOEXEC) != 0 || pipe2(reply, O_CLOEXEC) != 0) {
        snprintf(err, errlen, "pipe: %s", strerror(errno));
        return -1;
    }
    char seed_s[32], pre_s[64];
    snprintf(seed_s, sizeof seed_s, "%ld", seed);
    snprintf(pre_s, sizeof pre_s, "%.17g", precompression_pct);
    const char *argv[] = {python, "-m", "controller.sim.plant_bridge", "--seed", seed_s,
                          "--script", script, "--precompression", pre_s,
                          loop ? "--loop" : NULL, NULL};
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid < 0) {
        snprintf(err, errlen, "fork: %s", strerror(errno));
        return -1;
    }
    if (pid == 0) {
        /* Own process group: a Ctrl-C at the terminal reaches the device, which then
         * ends the bridge in order. Dies with the device, even by SIGKILL. */
        setpgid(0, 0);
        prctl(PR_SET_PDEATHSIG, SIGTERM, 0, 0, 0);
        if (getppid() != parent)
            _exit(4);
        sigset_t none;
        sigemptyset(&none);
        sigprocmask(SIG_SETMASK, &none, NULL);
        signal(SIGPIPE, SIG_DFL);
        if (dup2(cmd[0], 0) < 0 || dup2(reply[1], 1) < 0)
            _exit(5);
        if (repo_root != NULL) {
            const char *old = getenv("PYTHONPATH");
            size_t len = strlen(repo_root) + (old ? strlen(old) + 1 : 0) + 1;
            char *path = malloc(len);
            if (path != NULL) {
                snprintf(path, len, "%s%s%s", repo_root, old ? ":" : "", old ? old : "");
                setenv("PYTHONPATH", path, 1);
            }
        }
        execvp(python, (char *const *)argv);
        fprintf(stderr, "exostudy-device: cannot run %s: %s\n", python, strerror(errno));
        _exit(127);
    }
    close(cmd[0]);
    close(reply[1]);
    p->pid = pid;
    p->to_child = cmd[1];
    p->from_child = reply[0];
    uint8_t ready[PLANT_READY_BYTES];
    if (read_full(p->from_child, ready, sizeof ready, ready_timeout_ms) != 0 ||
        memcmp(ready, PLANT_READY, PLANT_READY_BYTES) != 0) {
        int status = 0, exited = 0;
        for (int i = 0; i < 100 && !exited; i++) { /* an end of input: it is exiting */
            exited = waitpid(pid, &status, WNOHANG) == pid;
            if (!exited) {
                struct timespec ts = {0, 10 * 1000 * 1000};
                nanosleep(&ts, NULL);
            }
        }
        if (exited) {
            p->pid = -1;
            snprintf(err, errlen,
                     "the simulated wearer (%s -m controller.sim.plant_bridge) exited with "
                     "code %d before it was ready (its message is above)",
                     python, WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status));
        } else {
            snprintf(err, errlen,
                     "the simulated wearer (%s -m controller.sim.plant_bridge) was not ready "
                     "within %d s",
                     python, ready_timeout_ms / 1000);
        }
        plant_close(p);
        return -1;
    }
    return 0;
}

static uint16_t le16(const uint8_t *b) { return (uint16_t)(b[0] | b[1] << 8); }
static uint32_t le32(const uint8_t *b) {
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

static int step_python(plant *p, int left, int right, plant_reading *out) {
    uint8_t cmd[PLANT_COMMAND_BYTES] = {'C', (uint8_t)((left ? 1 : 0) | (right ? 2 : 0)), 0, 0};
    uint8_t r[PLANT_REPLY_BYTES];
    if (write_full(p->to_child, cmd, sizeof cmd) != 0 ||
        read_full(p->from_child, r, sizeof r, STEP_TIMEOUT_MS) != 0) {
        fprintf(stderr, "exostudy-device: the simulated wearer stopped answering\n");
        return -1;
    }
    if (r[0] != 'P' || r[1] != 'R' || r[26] > 64) {
        fprintf(stderr, "exostudy-device: the simulated wearer sent a bad record\n");
        return -1;
    }
    for (int i = 0; i < 4; i++) {
        out->counts[i] = le16(r + 2 + 2 * i);
        out->fault[i] = out->counts[i] > 16383;
    }
    out->status = le32(r + 10);
    uint64_t bits = 0;
    for (int i = 7; i >= 0; i--)
        bits = bits << 8 | r[14 + i];
    memcpy(&out->truth.progress, &bits, sizeof bits);
    out->truth.lift_index = (int32_t)le32(r + 22);
    out->truth.activity_len = r[26];
    memcpy(out->truth.activity, r + 28, 64);
    out->has_truth = 1;
    out->finished = (r[27] & PLANT_REPLY_FINISHED) != 0;
    return 0;
}

static int step_file(plant *p, plant_reading *out) {
    if (p->next_row >= p->n_rows)
        p->next_row = p->loop ? 0 : p->n_rows - 1;
    size_t row = p->next_row++;
    for (int i = 0; i < 4; i++) {
        out->counts[i] = p->rows[4 * row + (size_t)i];
        out->fault[i] = p->row_fault[4 * row + (size_t)i];
    }
    out->status = 0;
    out->has_truth = 0;
    out->finished = !p->loop && p->next_row >= p->n_rows;
    return 0;
}

int plant_step(plant *p, int left, int right, plant_reading *out) {
    memset(out, 0, sizeof *out);
    int r = p->rows != NULL ? step_file(p, out) : step_python(p, left, right, out);
    if (r == 0)
        p->steps++;
    return r;
}

void plant_close(plant *p) {
    if (p->to_child >= 0)
        close(p->to_child); /* end of input: the bridge returns */
    if (p->from_child >= 0)
        close(p->from_child);
    p->to_child = p->from_child = -1;
    if (p->pid > 0) {
        int status;
        for (int i = 0; i < 100; i++) { /* up to 1 s */
            if (waitpid(p->pid, &status, WNOHANG) == p->pid) {
                p->pid = -1;
                break;
            }
            struct timespec ts = {0, 10 * 1000 * 1000};
            nanosleep(&ts, NULL);
        }
        if (p->pid > 0) {
            kill(p->pid, SIGTERM);
            waitpid(p->pid, &status, 0);
            p->pid = -1;
        }
    }
    free(p->rows);
    free(p->row_fault);
    p->rows = NULL;
    p->row_fault = NULL;
}

/* ---- counts file ---------------------------------------------------------------- */

/* Split `line` at commas in place; returns the number of fields (at most `max`). */
static int split(char *line, char **fields, int max) {
    int n = 0;
    char *s = line;
    while (n < max) {
        fields[n++] = s;
        char *c = strchr(s, ',');
        if (c == NULL)
            break;
        *c = '\0';
        s = c + 1;
    }
    for (int i = 0; i < n; i++) { /* trim spaces, CR and quotes */
        char *f = fields[i];
        while (*f == ' ' || *f == '"')
            f++;
        char *e = f + strlen(f);
        while (e > f && (e[-1] == '\n' || e[-1] == '\r' || e[-1] == ' ' || e[-1] == '"'))
            *--e = '\0';
        fields[i] = f;
    }
    return n;
}

#define MAX_FIELDS 256

int plant_open_counts(plant *p, const char *path, int loop, char *err, size_t errlen) {
    plant_init(p);
    p->loop = loop;
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        snprintf(err, errlen, "--counts %s: %s", path, strerror(errno));
        return -1;
    }
    char *line = NULL;
    size_t cap = 0;
    char *fields[MAX_FIELDS];
    int col[4] = {-1, -1, -1, -1};
    static const char *const names[2][4] = {
        {"count_left_output", "count_left_cam", "count_right_output", "count_right_cam"},
        {"left_output", "left_cam", "right_output", "right_cam"}};
    if (getline(&line, &cap, f) < 0) {
        snprintf(err, errlen, "--counts %s: empty file", path);
        goto fail;
    }
    int nf = split(line, fields, MAX_FIELDS);
    for (int i = 0; i < nf; i++)
        for (int k = 0; k < 4; k++)
            if (strcmp(fields[i], names[0][k]) == 0 || strcmp(fields[i], names[1][k]) == 0)
                col[k] = i;
    for (int k = 0; k < 4; k++) {
        if (col[k] < 0) {
            snprintf(err, errlen, "--counts %s: the header has no column %s (or %s)", path,
                     names[0][k], names[1][k]);
            goto fail;
        }
    }
    size_t rows_cap = 0;
    size_t lineno = 1;
    while (getline(&line, &cap, f) >= 0) {
        lineno++;
        if (line[0] == '\n' || line[0] == '\0' || (line[0] == '\r' && line[1] == '\n'))
            continue;
        nf = split(line, fields, MAX_FIELDS);
        if (p->n_rows == rows_cap) {
            rows_cap = rows_cap ? 2 * rows_cap : 4096;
            uint16_t *rows = realloc(p->rows, rows_cap * 4 * sizeof *rows);
            uint8_t *faults = realloc(p->row_fault, rows_cap * 4);
            if (rows != NULL)
                p->rows = rows;
            if (faults != NULL)
                p->row_fault = faults;
            if (rows == NULL || faults == NULL) {
                snprintf(err, errlen, "--counts %s: out of memory at line %zu", path, lineno);
                goto fail;
            }
        }
        for (int k = 0; k < 4; k++) {
            size_t at = 4 * p->n_rows + (size_t)k;
            const char *cell = col[k] < nf ? fields[col[k]] : "";
            char *end;
            errno = 0;
            long v = strtol(cell, &end, 10);
            int ok = *cell != '\0' && *end == '\0' && errno == 0 && v >= 0 && v <= 16383;
            p->rows[at] = ok ? (uint16_t)v : 0;
            p->row_fault[at] = (uint8_t)!ok;
        }
        p->n_rows++;
    }
    if (p->n_rows == 0) {
        snprintf(err, errlen, "--counts %s: no data rows below the header", path);
        goto fail;
    }
    free(line);
    fclose(f);
    return 0;
fail:
    free(line);
    fclose(f);
    plant_close(p);
    return -1;
}
