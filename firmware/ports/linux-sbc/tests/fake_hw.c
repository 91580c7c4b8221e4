/*
 * fake_hw.c - an LD_PRELOAD shim that stands in for the SBC's hardware, so exo-sbc's
 * real main loop, sockets, SPI framing and GPIO calls run on a desktop:
 *
 *   - open() of "/fake/spidevN" gives a placeholder descriptor; SPI_IOC_* ioctls on it
 *     are answered by four pipelined AS5048A encoders (chip N, or all four along a
 *     daisy chain), with 8- or 16-bit words as exo-sbc configured;
 *   - libgpiod's chip and line calls are replaced; line values are printed to stdout
 *     as "solenoids left=L right=R" when they change. Lines are known by the order
 *     exo-sbc asks for them: left, right, then the heartbeat and the drivers readback,
 *     which reads as the monostable of the lab wiring would: high while the heartbeat
 *     changed less than 30 ms ago.
 *
 * Test equipment only (loopback-check in the Makefile); never part of the port.
 */
#include <dlfcn.h>
#include <fcntl.h>
#include <linux/spi/spidev.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

#define MAX_FD 1024

static int fake_chip[MAX_FD]; /* 0: not fake; else chip index + 1 */
static unsigned word_bits[MAX_FD];
static uint16_t pending[4];

static uint16_t parity(uint16_t v)
{
    v &= 0x7FFFu;
    unsigned ones = 0;
    for (uint16_t x = v; x; x &= (uint16_t)(x - 1u)) {
        ones++;
    }
    return (ones & 1u) ? (uint16_t)(v | 0x8000u) : v;
}

static uint16_t encoder(unsigned chip, uint16_t cmd)
{
    uint16_t out = pending[chip];
    uint16_t reg = cmd & 0x3FFFu, data = 0;
    if (reg == 0x3FFFu) {
        struct timespec ts;
        clock_gettime(CLOCK_MONOTONIC, &ts);
        data = (uint16_t)((1000u * chip + (unsigned)(ts.tv_nsec / 10000000)) & 0x3FFFu);
    } else if (reg == 0x3FFDu) {
        data = 0x0180u;
    }
    pending[chip] = parity(data);
    return out;
}

static int fake_open(const char *path)
{
    if (strncmp(path, "/fake/spidev", 12) != 0) {
        return -2;
    }
    int fd = dup(STDIN_FILENO);
    if (fd < 0 || fd >= MAX_FD) {
        return -1;
    }
    fake_chip[fd] = (path[12] - '0') + 1;
    word_bits[fd] = 8;
    return fd;
}

int open(const char *path, int flags, ...)
{
    int fd = fake_open(path);
    if (fd != -2) {
        return fd;
    }
    va_list ap;
    va_start(ap, flags);
    mode_t mode = (mode_t)va_arg(ap, int);
    va_end(ap);
    int (*real)(const char *, int, ...);
    *(void **)&real = dlsym(RTLD_NEXT, "open"); /* POSIX's way round ISO C's rule */
    return real(path, flags, mode);
}

int open64(const char *path, int flags, ...)
{
    int fd = fake_open(path);
    if (fd != -2) {
        return fd;
    }
    va_list ap;
    va_start(ap, flags);
    mode_t mode = (mode_t)va_arg(ap, int);
    va_end(ap);
    int (*real)(const char *, int, ...);
    *(void **)&real = dlsym(RTLD_NEXT, "open64");
    return real(path, flags, mode);
}

int ioctl(int fd, unsigned long req, ...)
{
    va_list ap;
    va_start(ap, req);
    void *arg = va_arg(ap, void *);
    va_end(ap);
    if (fd < 0 || fd >= MAX_FD || fake_chip[fd] == 0) {
        int (*real)(int, unsigned long, ...);
        *(void **)&real = dlsym(RTLD_NEXT, "ioctl");
        return real(fd, req, arg);
    }
    if (req == SPI_IOC_WR_BITS_PER_WORD) {
        word_bits[fd] = *(uint8_t *)arg;
        return 0;
    }
    if (req != SPI_IOC_MESSAGE(1)) {
        return 0; /* mode, bit order, speed: accepted */
    }
    struct spi_ioc_transfer *t = arg;
    unsigned frames = t->len / 2u;
    unsigned chip = (unsigned)fake_chip[fd] - 1u;
    for (unsigned i = 0; i < frames; i++) {
        unsigned c = frames > 1u ? i : chip;
        if ((t->bits_per_word ? t->bits_per_word : word_bits[fd]) == 16u) {
            const uint16_t *tx = (const uint16_t *)(uintptr_t)t->tx_buf;
            uint16_t *rx = (uint16_t *)(uintptr_t)t->rx_buf;
            rx[i] = encoder(c, tx[i]);
        } else {
            const uint8_t *tx = (const uint8_t *)(uintptr_t)t->tx_buf;
            uint8_t *rx = (uint8_t *)(uintptr_t)t->rx_buf;
            uint16_t out = encoder(c, (uint16_t)(tx[2 * i] << 8 | tx[2 * i + 1]));
            rx[2 * i] = (uint8_t)(out >> 8);
            rx[2 * i + 1] = (uint8_t)out;
        }
    }
    return (int)t->len;
}

/* libgpiod v1 replacements. Line i is the i-th offset asked for: 0 left, 1 right,
 * 2 heartbeat, 3 drivers readback. */
#define LINES 4
#define HOLD_NS 30000000LL /* the lab monostable's hold, 30 ms */
static int chip_token, line_tokens[LINES], values[LINES] = {-1, -1, -1, -1}, requested[LINES];
static unsigned line_offsets[LINES];
static int lines_known;
static long long last_edge_ns = -1;

static long long mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (long long)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static int line_index(void *line)
{
    return (int)((int *)line - line_tokens);
}

void *gpiod_chip_open_lookup(const char *descr)
{
    (void)descr;
    return &chip_token;
}

void *gpiod_chip_get_line(void *chip, unsigned offset)
{
    (void)chip;
    for (int i = 0; i < lines_known; i++) {
        if (line_offsets[i] == offset) {
            return &line_tokens[i];
        }
    }
    if (lines_known == LINES) {
        return NULL;
    }
    line_offsets[lines_known] = offset;
    return &line_tokens[lines_known++];
}

int gpiod_line_request_output(void *line, const char *consumer, int value)
{
    (void)consumer;
    int i = line_index(line);
    requested[i] = 1;
    values[i] = value;
    return 0;
}

int gpiod_line_request_input(void *line, const char *consumer)
{
    (void)consumer;
    requested[line_index(line)] = 1;
    return 0;
}

int gpiod_line_set_value(void *line, int value)
{
    int i = line_index(line);
    if (!requested[i]) {
        return -1;
    }
    if (values[i] != value) {
        values[i] = value;
        if (i == 2) {
            last_edge_ns = mono_ns(); /* retriggers the monostable */
        } else {
            printf("solenoids left=%d right=%d\n", values[0], values[1]);
            fflush(stdout);
        }
    }
    return 0;
}

int gpiod_line_get_value(void *line)
{
    int i = line_index(line);
    if (!requested[i]) {
        return -1;
    }
    if (i == 3) {
        return last_edge_ns >= 0 && mono_ns() - last_edge_ns < HOLD_NS;
    }
    return values[i];
}

void gpiod_line_release(void *line)
{
    requested[line_index(line)] = 0;
}

void gpiod_chip_close(void *chip)
{
    (void)chip;
}
