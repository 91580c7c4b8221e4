/*
 * tap-bench.c - the Nucleo port's network stack and the device core, run as a Linux
 * process on a TAP interface: a check of everything but the MCU's drivers, with the
 * Linux kernel's own ARP/IPv4/UDP on the other side and ExoStudy's real host code
 * (UdpDevice) above it. Four simulated encoders answer the core's SPI frames; the
 * solenoid state is printed when it changes.
 *
 *   tap-bench --key-file FILE [--seconds S]     (needs CAP_NET_ADMIN and /dev/net/tun)
 *
 * It creates exotap0 with the host side 192.168.250.1/24; the "device" is
 * 192.168.250.2 (MAC 02:45:58:00:00:02), port 47300. The interface disappears when it
 * exits. tap_check.py drives it from Python. Not part of the firmware.
 */
#include <errno.h>
#include <fcntl.h>
#include <linux/if.h>
#include <linux/if_tun.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "../net/net_stack.h"
#include "exo_device.h"
#include "hmac.h"
#include "sbc_key.h"

#define HOST_IP 0xC0A8FA01u   /* 192.168.250.1 */
#define DEVICE_IP 0xC0A8FA02u /* 192.168.250.2 */

static volatile sig_atomic_t stop_requested;
static int tap_fd = -1;
static net_stack net;
static exo_device dev;
static uint16_t pending[4];
static int sol_left = -1, sol_right = -1;

static uint64_t now_us(void *ctx)
{
    (void)ctx;
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static uint16_t parity(uint16_t v)
{
    v &= 0x7FFFu;
    unsigned ones = 0;
    for (uint16_t x = v; x; x &= (uint16_t)(x - 1u)) {
        ones++;
    }
    return (ones & 1u) ? (uint16_t)(v | 0x8000u) : v;
}

/* A pipelined AS5048A: each frame returns the answer to the previous command. */
static int spi(void *ctx, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n)
{
    (void)ctx;
    for (size_t i = 0; i < n; i++) {
        unsigned c = n > 1 ? (unsigned)i : chip;
        rx[i] = pending[c];
        uint16_t reg = tx[i] & 0x3FFFu;
        uint16_t data = 0;
        if (reg == 0x3FFFu) {
            data = (uint16_t)((1000u * c + now_us(NULL) / 10000u) & 0x3FFFu);
        } else if (reg == 0x3FFDu) {
            data = 0x0180u; /* offset compensation finished, AGC 128 */
        }
        pending[c] = parity(data);
    }
    return 0;
}

static void solenoids(void *ctx, int left, int right)
{
    (void)ctx;
    if (left != sol_left || right != sol_right) {
        printf("solenoids left=%d right=%d\n", left, right);
        fflush(stdout);
        sol_left = left;
        sol_right = right;
    }
}

static int link_send(void *ctx, const uint8_t *frame, size_t len)
{
    (void)ctx;
    return write(tap_fd, frame, len) == (ssize_t)len ? 0 : -1;
}

static int send_udp(void *ctx, const uint8_t *data, size_t len, exo_endpoint to)
{
    (void)ctx;
    return net_stack_send_udp(&net, to.ip, to.port, data, len, now_us(NULL));
}

static long receive(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from)
{
    (void)ctx;
    if (net.rx_count == 0u) {
        return EXO_RX_NONE; /* as board.c: an empty datagram is length 0, not "none" */
    }
    return net_stack_receive(&net, buf, cap, &from->ip, &from->port);
}

static int random_bytes(void *ctx, uint8_t *out, size_t n)
{
    (void)ctx;
    return getrandom(out, n, 0) == (ssize_t)n ? 0 : -1;
}

static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

static void die(const char *what)
{
    fprintf(stderr, "tap-bench: %s: %s\n", what, strerror(errno));
    exit(2);
}

static void configure_host_side(const char *ifname)
{
    int s = socket(AF_INET, SOCK_DGRAM, 0);
    struct ifreq r;
    memset(&r, 0, sizeof r);
    snprintf(r.ifr_name, IFNAMSIZ, "%s", ifname);
    struct sockaddr_in *a = (struct sockaddr_in *)&r.ifr_addr;
    a->sin_family = AF_INET;
    a->sin_addr.s_addr = htonl(HOST_IP);
    if (ioctl(s, SIOCSIFADDR, &r) < 0) {
        die("SIOCSIFADDR");
    }
    a->sin_addr.s_addr = htonl(0xFFFFFF00u);
    if (ioctl(s, SIOCSIFNETMASK, &r) < 0) {
        die("SIOCSIFNETMASK");
    }
    if (ioctl(s, SIOCGIFFLAGS, &r) < 0) {
        die("SIOCGIFFLAGS");
    }
    r.ifr_flags |= IFF_UP | IFF_RUNNING;
    if (ioctl(s, SIOCSIFFLAGS, &r) < 0) {
        die("SIOCSIFFLAGS");
    }
    close(s);
}

int main(int argc, char **argv)
{
    const char *key_file = NULL;
    double seconds = 10.0;
    for (int i = 1; i + 1 < argc; i += 2) {
        if (strcmp(argv[i], "--key-file") == 0) {
            key_file = argv[i + 1];
        } else if (strcmp(argv[i], "--seconds") == 0) {
            seconds = atof(argv[i + 1]);
        }
    }
    if (key_file == NULL) {
        fprintf(stderr, "usage: tap-bench --key-file FILE [--seconds S]\n");
        return 2;
    }
    exo_config cfg;
    memset(&cfg, 0, sizeof cfg);
    char err[256];
    if (sbc_key_load(key_file, cfg.key, err, sizeof err) != 0) {
        fprintf(stderr, "tap-bench: %s\n", err);
        return 2;
    }
    tap_fd = open("/dev/net/tun", O_RDWR | O_CLOEXEC);
    if (tap_fd < 0) {
        die("/dev/net/tun");
    }
    struct ifreq r;
    memset(&r, 0, sizeof r);
    r.ifr_flags = IFF_TAP | IFF_NO_PI;
    strcpy(r.ifr_name, "exotap0");
    if (ioctl(tap_fd, TUNSETIFF, &r) < 0) {
        die("TUNSETIFF (needs CAP_NET_ADMIN)");
    }
    configure_host_side(r.ifr_name);

    net_config ncfg = {.mac = {0x02, 0x45, 0x58, 0x00, 0x00, 0x02},
                       .ip = DEVICE_IP,
                       .netmask = 0xFFFFFF00u,
                       .udp_port = 47300,
                       .peer_ip = HOST_IP};
    net_stack_init(&net, &ncfg, link_send, NULL);
    exo_board b;
    memset(&b, 0, sizeof b);
    b.now_us = now_us;
    b.spi_transfer = spi;
    b.set_solenoids = solenoids;
    b.send = send_udp;
    b.receive = receive;
    b.random_bytes = random_bytes;
    cfg.host_ip = HOST_IP;
    cfg.bus = EXO_BUS_CHIP_SELECTS;
    cfg.rate_factor = 1;
    memcpy(cfg.firmware, "exo-nucleo 3", 12); /* what the board sends */
    memcpy(cfg.unique_id, "tap-bench", 9);
    int rc = exo_device_init(&dev, &b, &cfg);
    exo_secure_zero(cfg.key, sizeof cfg.key);
    if (rc != 0) {
        fprintf(stderr, "tap-bench: the core refused to start\n");
        return 2;
    }
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    printf("ready %s\n", r.ifr_name);
    fflush(stdout);

    uint64_t end = now_us(NULL) + (uint64_t)(seconds * 1e6);
    uint64_t due = 0;
    static uint8_t frame[2048];
    while (!stop_requested && now_us(NULL) < end) {
        uint64_t now = now_us(NULL);
        int timeout_ms = due > now ? (int)((due - now) / 1000u) : 0;
        struct pollfd p = {tap_fd, POLLIN, 0};
        if (poll(&p, 1, timeout_ms) > 0) {
            ssize_t n = read(tap_fd, frame, sizeof frame);
            if (n > 0) {
                net_stack_input(&net, frame, (size_t)n, now_us(NULL));
            }
        }
        if (net.rx_count > 0u || now_us(NULL) >= due) {
            due = now_us(NULL) + exo_device_poll(&dev);
        }
    }
    exo_device_stop(&dev);
    printf("net frames_in=%u frames_out=%u arp_replies=%u arp_requests=%u ipv4_errors=%u "
           "udp_errors=%u icmp=%u\n",
           net.stats.frames_in, net.stats.frames_out, net.stats.arp_replies_sent,
           net.stats.arp_requests_sent, net.stats.ipv4_errors, net.stats.udp_errors,
           net.stats.icmp_echo_replies);
    printf("core samples=%llu commands=%llu hellos=%llu auth_failures=%llu releases=%llu\n",
           (unsigned long long)dev.stats.samples_sent, (unsigned long long)dev.stats.commands,
           (unsigned long long)dev.stats.hellos,
           (unsigned long long)dev.stats.malformed[EXO_DROP_AUTH],
           (unsigned long long)dev.stats.watchdog_releases);
    close(tap_fd);
    return 0;
}
