/*
 * main.c - `exostudy-device`: the portable device core on Linux, against the simulated
 * wearer. The same command line as `exostudy device-sim` (the Python reference
 * device), the same one-line JSON statistics on exit, so the server, the tests and the
 * benchmarks can run either and compare them. The "hardware" is the Python
 * SimulatedExoskeleton run as a child (controller/sim/plant_bridge.py), or a recorded
 * counts file (--counts) with no Python at all. See docs/device-firmware.md.
 */
#include <arpa/inet.h>
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "board.h"
#include "exo_device.h"
#include "plant.h"
#include "stats.h"

#define PROG "exostudy-device"
/* The firmware name in this simulator's CHALLENGEs (at most 16 printable characters). */
#define LINUX_SIM_FIRMWARE "exo-linux-sim 3"
#define DEFAULT_PORT 47300
/* The interpreter start and imports of the simulated wearer: about 1 s idle; a loaded
 * two-core machine needs far more (the server waits 20 s for the port). */
#define PLANT_READY_TIMEOUT_MS 60000

static volatile sig_atomic_t stop_requested;

static void on_signal(int sig) {
    (void)sig;
    stop_requested = 1;
}

typedef struct {
    int port;
    long seed;
    const char *script;
    const char *host;
    const char *bind;
    double precompression;
    int loop;
    double duration; /* < 0: none */
    int realtime;
    const char *key_file;
    int rate_factor;
    const char *counts;
    const char *python;
    const char *device_id; /* NULL: derived from the key */
} options;

static void usage(FILE *out) {
    fprintf(out,
            "usage: " PROG " --key-file FILE [--port P] [--seed S] [--script NAME]\n"
            "       [--host IP] [--bind ADDR] [--precompression PCT] [--no-loop]\n"
            "       [--duration S] [--realtime] [--rate-factor N] [--counts FILE.csv]\n"
            "       [--python PATH] [--device-id HEX]\n\n"
            "The ExoStudy device firmware core on Linux against the simulated wearer; the\n"
            "arguments of `exostudy device-sim`. --counts replays a counts CSV instead of\n"
            "the simulated wearer; --python is the interpreter that runs the wearer\n"
            "(default: $EXOSTUDY_PYTHON, else the checkout's .venv, else python3).\n"
            "--device-id is the unique id its CHALLENGEs report, 1..32 hex digits\n"
            "(default: derived from the key, as the Python simulator does).\n");
}

static void die_usage(const char *fmt, const char *arg) {
    usage(stderr);
    fprintf(stderr, PROG ": error: ");
    fprintf(stderr, fmt, arg);
    fputc('\n', stderr);
    exit(2);
}

static long parse_long(const char *s, const char *what) {
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (*s == '\0' || *end != '\0' || errno != 0)
        die_usage("argument %s: not an integer", what);
    return v;
}

static double parse_double(const char *s, const char *what) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (*s == '\0' || *end != '\0' || errno != 0 || !isfinite(v))
        die_usage("argument %s: not a number", what);
    return v;
}

static void parse_args(int argc, char **argv, options *o) {
    enum { O_PORT = 1, O_SEED, O_SCRIPT, O_HOST, O_BIND, O_PRE, O_NOLOOP, O_DURATION,
           O_REALTIME, O_KEY, O_RATE, O_COUNTS, O_PYTHON, O_DEVICE_ID, O_HELP };
    static const struct option longopts[] = {
        {"port", required_argument, NULL, O_PORT},
        {"seed", required_argument, NULL, O_SEED},
        {"script", required_argument, NULL, O_SCRIPT},
        {"host", required_argument, NULL, O_HOST},
        {"bind", required_argument, NULL, O_BIND},
        {"precompression", required_argument, NULL, O_PRE},
        {"no-loop", no_argument, NULL, O_NOLOOP},
        {"duration", required_argument, NULL, O_DURATION},
        {"realtime", no_argument, NULL, O_REALTIME},
        {"key-file", required_argument, NULL, O_KEY},
        {"rate-factor", required_argument, NULL, O_RATE},
        {"counts", required_argument, NULL, O_COUNTS},
        {"python", required_argument, NULL, O_PYTHON},
        {"device-id", required_argument, NULL, O_DEVICE_ID},
        {"help", no_argument, NULL, O_HELP},
        {NULL, 0, NULL, 0}};
    *o = (options){.port = DEFAULT_PORT, .seed = 0, .script = "paper-evaluation",
                   .host = "127.0.0.1", .bind = NULL, .precompression = 25.0, .loop = 1,
                   .duration = -1.0, .realtime = 0, .key_file = NULL, .rate_factor = 1,
                   .counts = NULL, .python = NULL, .device_id = NULL};
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, "", longopts, NULL)) != -1) {
        switch (c) {
        case O_PORT: {
            long p = parse_long(optarg, "--port");
            if (p < 0 || p > 65535)
                die_usage("argument --port: %s is not a port (0..65535)", optarg);
            o->port = (int)p;
            break;
        }
        case O_SEED: o->seed = parse_long(optarg, "--seed"); break;
        case O_SCRIPT: o->script = optarg; break;
        case O_HOST: o->host = optarg; break;
        case O_BIND: o->bind = optarg; break;
        case O_PRE: o->precompression = parse_double(optarg, "--precompression"); break;
        case O_NOLOOP: o->loop = 0; break;
        case O_DURATION: o->duration = parse_double(optarg, "--duration"); break;
        case O_REALTIME: o->realtime = 1; break;
        case O_KEY: o->key_file = optarg; break;
        case O_RATE: {
            long r = parse_long(optarg, "--rate-factor");
            if (r < 1 || r > 100)
                die_usage("--rate-factor must be within 1..100 (got %s)", optarg);
            o->rate_factor = (int)r;
            break;
        }
        case O_COUNTS: o->counts = optarg; break;
        case O_PYTHON: o->python = optarg; break;
        case O_DEVICE_ID: o->device_id = optarg; break;
        case O_HELP: usage(stdout); exit(0);
        default:
            die_usage("unrecognized arguments: %s", argv[optind - 1]);
        }
    }
    if (optind < argc)
        die_usage("unrecognized arguments: %s", argv[optind]);
    if (o->key_file == NULL)
        die_usage("the following arguments are required: %s", "--key-file");
}

/* The link key: 64 hex digits (whitespace around them allowed), in a file only its
 * owner may read, as controller.device.auth.load_key demands. */
static void load_key(const char *path, uint8_t key[EXO_KEY_BYTES]) {
    struct stat st;
    char msg[PATH_MAX + 128];
    if (stat(path, &st) != 0) {
        snprintf(msg, sizeof msg, "%s: no device key file", path);
        die_usage("%s", msg);
    }
    if (st.st_mode & (S_IRWXG | S_IRWXO)) {
        snprintf(msg, sizeof msg, "%s: readable by others (mode %o); chmod 600 it", path,
                 (unsigned)(st.st_mode & 07777));
        die_usage("%s", msg);
    }
    FILE *f = fopen(path, "r");
    char text[256];
    size_t n = f ? fread(text, 1, sizeof text - 1, f) : 0;
    if (f)
        fclose(f);
    text[n] = '\0';
    char *s = text;
    while (*s == ' ' || *s == '\n' || *s == '\r' || *s == '\t')
        s++;
    char *e = s + strlen(s);
    while (e > s && (e[-1] == ' ' || e[-1] == '\n' || e[-1] == '\r' || e[-1] == '\t'))
        *--e = '\0';
    if ((size_t)(e - s) != 2 * EXO_KEY_BYTES) {
        snprintf(msg, sizeof msg, "%s: the key must be %d bytes (%d hex digits)", path,
                 EXO_KEY_BYTES, 2 * EXO_KEY_BYTES);
        die_usage("%s", msg);
    }
    for (int i = 0; i < EXO_KEY_BYTES; i++) {
        unsigned v;
        char pair[3] = {s[2 * i], s[2 * i + 1], '\0'};
        char *end;
        v = (unsigned)strtoul(pair, &end, 16);
        if (*end != '\0' || pair[0] == '+' || pair[0] == '-' || pair[0] == ' ') {
            snprintf(msg, sizeof msg, "%s: not hexadecimal", path);
            die_usage("%s", msg);
        }
        key[i] = (uint8_t)v;
    }
    exo_secure_zero(text, sizeof text); /* the key in hex */
}

/* The unique id a simulator reports: --device-id (1..32 hex digits, zero-padded to 16
 * bytes, an odd count completed with a 0 digit, as controller.device.auth
 * parse_unique_id), else the first 16 bytes of HMAC-SHA256(key, "exostudy simulated
 * device") (simulated_unique_id), so a hardware profile follows the simulated device
 * whichever implementation runs it. */
static void unique_id_for(const options *o, const uint8_t key[EXO_KEY_BYTES],
                          uint8_t out[EXO_UNIQUE_ID_BYTES]) {
    memset(out, 0, EXO_UNIQUE_ID_BYTES);
    if (o->device_id == NULL) {
        static const char label[] = "exostudy simulated device";
        exo_hmac_key k;
        uint8_t tag[EXO_TAG_BYTES];
        exo_hmac_set_key(&k, key, EXO_KEY_BYTES);
        exo_hmac_sha256(&k, (const uint8_t *)label, sizeof label - 1, NULL, 0, tag);
        memcpy(out, tag, EXO_UNIQUE_ID_BYTES);
        exo_secure_zero(&k, sizeof k);
        return;
    }
    size_t n = strlen(o->device_id);
    if (n < 1 || n > 2 * EXO_UNIQUE_ID_BYTES
        || strspn(o->device_id, "0123456789abcdefABCDEF") != n)
        die_usage("argument --device-id: device id '%s': expected 1..32 hex digits",
                  o->device_id);
    for (size_t i = 0; i < n; i++) {
        char c = o->device_id[i];
        unsigned v = (unsigned)(c <= '9' ? c - '0' : (c | 0x20) - 'a' + 10);
        out[i / 2] = (uint8_t)(out[i / 2] | (i % 2 ? v : v << 4));
    }
}

/* PR_SET_PDEATHSIG plus the EXOSTUDY_PARENT_PID check of backend/live/device_process.py:
 * a server-spawned device never outlives its server (it would keep the port). */
static void die_with_parent(void) {
    const char *expected = getenv("EXOSTUDY_PARENT_PID");
    if (expected == NULL || *expected == '\0')
        return;
    prctl(PR_SET_PDEATHSIG, SIGTERM, 0, 0, 0);
    if ((long)getppid() != strtol(expected, NULL, 10))
        exit(4);
}

static int resolve_ipv4(const char *name, uint32_t *ip) {
    struct addrinfo hints = {0}, *res = NULL;
    hints.ai_family = AF_INET;
    hints.ai_socktype = SOCK_DGRAM;
    if (getaddrinfo(name, NULL, &hints, &res) != 0 || res == NULL)
        return -1;
    *ip = ntohl(((struct sockaddr_in *)res->ai_addr)->sin_addr.s_addr);
    freeaddrinfo(res);
    return 0;
}

/* The checkout this binary was built in (firmware/build/ -> ../..), if it has the
 * Python package; NULL otherwise. */
static const char *repo_root(void) {
    static char root[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", root, sizeof root - 1);
    if (n <= 0)
        return NULL;
    root[n] = '\0';
    for (int up = 0; up < 3; up++) {
        char *slash = strrchr(root, '/');
        if (slash == NULL)
            return NULL;
        *slash = '\0';
    }
    char probe[PATH_MAX + 64];
    snprintf(probe, sizeof probe, "%s/controller/sim/plant_bridge.py", root);
    return access(probe, R_OK) == 0 ? root : NULL;
}

static const char *python_for(const options *o, const char *root) {
    if (o->python != NULL)
        return o->python;
    const char *env = getenv("EXOSTUDY_PYTHON");
    if (env != NULL && *env != '\0')
        return env;
    static char venv[PATH_MAX + 32];
    if (root != NULL) {
        snprintf(venv, sizeof venv, "%s/.venv/bin/python", root);
        if (access(venv, X_OK) == 0)
            return venv;
    }
    return "python3";
}

static const char *realtime(void) {
    struct sched_param sp = {.sched_priority = 10};
    static char msg[160];
    if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0) {
        snprintf(msg, sizeof msg,
                 "real-time scheduling not available (%s); running normally", strerror(errno));
        return msg;
    }
    return "running with SCHED_FIFO priority 10";
}

static exo_device device; /* static: the core never allocates */

int main(int argc, char **argv) {
    die_with_parent();
    options o;
    parse_args(argc, argv, &o);
    exo_config cfg;
    memset(&cfg, 0, sizeof cfg);
    load_key(o.key_file, cfg.key);
    uint32_t host_ip;
    if (resolve_ipv4(o.host, &host_ip) != 0)
        die_usage("--host %s: not an IPv4 address or known host name", o.host);
    const char *bind_to = o.bind ? o.bind : (strncmp(o.host, "127.", 4) == 0 ? "127.0.0.1"
                                                                          : "0.0.0.0");
    uint32_t bind_ip;
    if (resolve_ipv4(bind_to, &bind_ip) != 0)
        die_usage("--bind %s: not an IPv4 address or known host name", bind_to);
    cfg.host_ip = host_ip;
    cfg.sample_period_us = EXO_SAMPLE_PERIOD_US;
    cfg.rate_factor = (uint32_t)o.rate_factor;
    cfg.bus = EXO_BUS_CHIP_SELECTS;
    unique_id_for(&o, cfg.key, cfg.unique_id);
    memcpy(cfg.firmware, LINUX_SIM_FIRMWARE, sizeof LINUX_SIM_FIRMWARE - 1);

    signal(SIGPIPE, SIG_IGN); /* a dead wearer shows as a failed write, not a kill */

    if (o.realtime)
        fprintf(stderr, PROG ": %s\n", realtime());

    /* The wearer first (its start-up costs are paid before the port is bound, so the
     * server's "it holds the port" means it is ready and the first samples are not
     * late), then the socket. */
    plant wearer;
    char err[PATH_MAX + 256];
    const char *root = repo_root();
    if (o.counts != NULL) {
        if (plant_open_counts(&wearer, o.counts, o.loop, err, sizeof err) != 0) {
            fprintf(stderr, PROG ": error: %s\n", err);
            return 2;
        }
    } else if (plant_start_python(&wearer, python_for(&o, root), root, o.seed, o.script,
                                  o.precompression, o.loop, PLANT_READY_TIMEOUT_MS, err,
                                  sizeof err) != 0) {
        fprintf(stderr, PROG ": error: %s\n", err);
        return 3;
    }

    int sock = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    struct sockaddr_in addr = {0};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(bind_ip);
    addr.sin_port = htons((uint16_t)o.port);
    if (sock < 0 || bind(sock, (struct sockaddr *)&addr, sizeof addr) != 0) {
        fprintf(stderr, PROG ": error: cannot bind UDP %s:%d: %s\n", bind_to, o.port,
                strerror(errno));
        plant_close(&wearer);
        return 3;
    }

    /* From here on the device has state to wind down: SIGINT and SIGTERM set a flag and
     * are blocked except inside ppoll, so one can never slip in between the check of
     * the flag and the wait. (Before, while the wearer starts, they end the process at
     * once: nothing is energised yet, and the wearer dies with it.) */
    struct sigaction sa = {0};
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    sigset_t blocked, waitmask;
    sigemptyset(&blocked);
    sigaddset(&blocked, SIGINT);
    sigaddset(&blocked, SIGTERM);
    sigprocmask(SIG_BLOCK, &blocked, &waitmask);
    sigdelset(&waitmask, SIGINT);
    sigdelset(&waitmask, SIGTERM);

    linux_sim_board ctx;
    exo_board board;
    linux_sim_board_init(&ctx, &board, sock, &wearer, host_ip);
    ctx.rate_factor = (unsigned)o.rate_factor;
    linux_sim_stats stats;
    linux_sim_stats_init(&stats, &ctx);
    ctx.hold = 1; /* init releases the solenoids: that is no sample period */
    int init_failed = exo_device_init(&device, &board, &cfg) != 0;
    exo_secure_zero(cfg.key, sizeof cfg.key); /* the core keeps only its absorbed state */
    ctx.hold = 0;
    if (init_failed) {
        fprintf(stderr, PROG ": error: no entropy for the session number (getrandom)\n");
        plant_close(&wearer);
        close(sock);
        return 3;
    }
    if (o.counts != NULL)
        fprintf(stderr, PROG ": listening on %s:%d, host %s, replaying counts from %s\n",
                bind_to, o.port, o.host, o.counts);
    else
        fprintf(stderr, PROG ": listening on %s:%d, host %s, script '%s', seed %ld\n", bind_to,
                o.port, o.host, o.script, o.seed);

    uint64_t began = linux_sim_now_us();
    uint64_t end = o.duration >= 0 ? began + (uint64_t)(o.duration * 1e6) : UINT64_MAX;
    int code = 0;
    while (!stop_requested) {
        uint32_t wait_us = exo_device_poll(&device);
        linux_sim_stats_after_poll(&stats, &device);
        if (ctx.plant_failed) {
            fprintf(stderr, PROG ": error: the simulated wearer is gone; stopping\n");
            code = 3;
            break;
        }
        if (!o.loop && ctx.finished)
            break; /* the script's last sample went out in this poll */
        uint64_t now = linux_sim_now_us();
        if (now >= end)
            break;
        if (end - now < wait_us)
            wait_us = (uint32_t)(end - now);
        struct pollfd pfd = {.fd = sock, .events = POLLIN};
        struct timespec ts = {.tv_sec = wait_us / 1000000u,
                              .tv_nsec = (long)(wait_us % 1000000u) * 1000L};
        ppoll(&pfd, 1, &ts, &waitmask);
    }
    ctx.hold = 1;
    exo_device_stop(&device); /* solenoids released before anything else */
    linux_sim_stats_print(&stats, &device, stdout);
    fflush(stdout);
    plant_close(&wearer);
    close(sock);
    return code;
}
