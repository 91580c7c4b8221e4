/* exo-sbc's helpers: options, key file, identity, SPI byte framing, the UDP socket
 * (every datagram counted, empty ones included) and the GPIO lines (heartbeat and
 * drivers readback) against an in-memory libgpiod. */
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../../test-harness/harness.h"

#include "../sbc_gpio.h"
#include "../sbc_identity.h"
#include "../sbc_key.h"
#include "../sbc_options.h"
#include "../sbc_spi_frames.h"
#include "../sbc_udp.h"
#include "fake_gpiod.h"
#include "wire.h"

int harness_passed;
int harness_failed;

#define ARGC(a) ((int)(sizeof(a) / sizeof(a[0])))

static const char *CS4 = "/dev/spidev0.0,/dev/spidev0.1,/dev/spidev1.0,/dev/spidev1.1";

static int parse(int argc, const char **argv, sbc_options *o, char *err)
{
    return sbc_options_parse(argc, (char **)argv, o, err, 256);
}

static void options_good(void)
{
    sbc_options o;
    char err[256] = "";
    const char *a[] = {"exo-sbc", "--key-file", "var/device.key", "--host", "192.168.50.1",
                       "--spidev", CS4, "--solenoid-lines", "17,27"};
    CHECK_EQ(parse(ARGC(a), a, &o, err), 0);
    CHECK(strcmp(o.key_file, "var/device.key") == 0);
    CHECK_EQ(o.host_ip, 0xC0A83201u);
    CHECK_EQ(o.port, 47300u);
    CHECK_EQ(o.bind_ip, 0u);
    CHECK_EQ(o.bus, SBC_BUS_CHIP_SELECTS);
    CHECK_EQ(o.n_spidev, 4u);
    CHECK(strcmp(o.spidev[2], "/dev/spidev1.0") == 0);
    CHECK_EQ(o.spi_hz, 1000000u);
    CHECK_EQ(o.spi_word_bits, 8u);
    CHECK(strcmp(o.gpiochip, "gpiochip0") == 0);
    CHECK_EQ(o.line_left, 17u);
    CHECK_EQ(o.line_right, 27u);
    CHECK(strcmp(o.watchdog, "/dev/watchdog") == 0);
    CHECK_EQ(o.realtime, 1);
    CHECK(o.duration_s < 0);

    const char *b[] = {"exo-sbc", "--key-file=k", "--host=10.0.0.2", "--bus", "daisy-chain",
                       "--spidev", "/dev/spidev0.0", "--solenoid-lines=5,6", "--port", "5000",
                       "--bind", "10.0.0.3", "--spi-hz", "10000000", "--spi-word", "16",
                       "--gpiochip", "/dev/gpiochip4", "--watchdog", "none",
                       "--watchdog-timeout", "3", "--priority", "80", "--no-realtime",
                       "--duration", "2.5"};
    CHECK_EQ(parse(ARGC(b), b, &o, err), 0);
    CHECK_EQ(o.bus, SBC_BUS_DAISY_CHAIN);
    CHECK_EQ(o.n_spidev, 1u);
    CHECK_EQ(o.port, 5000u);
    CHECK_EQ(o.bind_ip, 0x0A000003u);
    CHECK_EQ(o.spi_hz, 10000000u);
    CHECK_EQ(o.spi_word_bits, 16u);
    CHECK(strcmp(o.gpiochip, "/dev/gpiochip4") == 0);
    CHECK_EQ(o.watchdog[0], 0);
    CHECK_EQ(o.watchdog_timeout_s, 3u);
    CHECK_EQ(o.priority, 80);
    CHECK_EQ(o.realtime, 0);
    CHECK(o.duration_s == 2.5);

    CHECK_EQ(o.has_heartbeat_line, 0);
    CHECK_EQ(o.has_drivers_line, 0);
    CHECK_EQ(o.has_device_id, 0);

    const char *c[] = {"exo-sbc", "--key-file", "k", "--host", "10.0.0.2", "--spidev", CS4,
                       "--solenoid-lines", "17,27", "--heartbeat-line", "22",
                       "--drivers-line=0", "--device-id", "0123456789ABCDEF0123456789abcdef"};
    CHECK_EQ(parse(ARGC(c), c, &o, err), 0);
    CHECK_EQ(o.has_heartbeat_line, 1);
    CHECK_EQ(o.line_heartbeat, 22u);
    CHECK_EQ(o.has_drivers_line, 1);
    CHECK_EQ(o.line_drivers, 0u);
    CHECK_EQ(o.has_device_id, 1);
    CHECK_EQ(o.device_id[0], 0x01u);
    CHECK_EQ(o.device_id[15], 0xEFu);

    const char *h[] = {"exo-sbc", "--host", "bad", "--help"};
    CHECK_EQ(parse(ARGC(h), h, &o, err), -1); /* the error comes first, in order */
    const char *h2[] = {"exo-sbc", "--help"};
    CHECK_EQ(parse(ARGC(h2), h2, &o, err), 1);
}

/* Each case replaces one argument of a good command line; the error names it. */
static void options_bad(void)
{
    struct {
        const char *flag;
        const char *value;
        const char *named;
    } cases[] = {
        {"--host", "192.168.50", "--host"},      {"--host", "192.168.050.1", "--host"},
        {"--host", "256.1.1.1", "--host"},       {"--host", "0.0.0.0", "--host"},
        {"--host", "1.2.3.4x", "--host"},        {"--port", "0", "--port"},
        {"--port", "65536", "--port"},           {"--port", "-1", "--port"},
        {"--bus", "ring", "--bus"},              {"--spidev", "/a,/b", "chip-selects"},
        {"--spidev", "/a,,/b,/c", "--spidev"},   {"--spidev", "/a,/b,/c,/d,/e", "--spidev"},
        {"--spi-hz", "20000000", "--spi-hz"},    {"--spi-hz", "1e6", "--spi-hz"},
        {"--spi-word", "12", "--spi-word"},      {"--solenoid-lines", "17", "--solenoid"},
        {"--solenoid-lines", "17,17", "--solenoid"}, {"--solenoid-lines", "a,b", "--solenoid"},
        {"--priority", "100", "--priority"},     {"--priority", "0", "--priority"},
        {"--watchdog-timeout", "0", "--watchdog-timeout"}, {"--duration", "0", "--duration"},
        {"--duration", "abc", "--duration"},     {"--colour", "red", "--colour"},
        {"--heartbeat-line", "1", "heartbeat"},  {"--heartbeat-line", "2", "heartbeat"},
        {"--heartbeat-line", "x", "--heartbeat-line"}, {"--heartbeat-line", "4096", "--heartbeat-line"},
        {"--drivers-line", "2", "drivers"},      {"--drivers-line", "-3", "--drivers-line"},
        {"--device-id", "", "--device-id"},      {"--device-id", "12g4", "--device-id"},
        {"--device-id", "000000000000000000000000000000001", "--device-id"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *a[] = {"exo-sbc",    "--key-file", "k",   "--host", "192.168.50.1",
                           "--spidev",   CS4,          "--solenoid-lines", "1,2",
                           cases[i].flag, cases[i].value};
        sbc_options o;
        char err[256] = "";
        int rc = parse(ARGC(a), a, &o, err);
        CHECK_EQ(rc, -1);
        if (strstr(err, cases[i].named) == NULL) {
            harness_failed++;
            fprintf(stderr, "case %zu (%s %s): error '%s' does not name %s\n", i,
                    cases[i].flag, cases[i].value, err, cases[i].named);
        } else {
            harness_passed++;
        }
    }

    sbc_options o;
    char err[256] = "";
    const char *missing_key[] = {"exo-sbc", "--host", "1.2.3.4", "--spidev", CS4,
                                 "--solenoid-lines", "1,2"};
    CHECK_EQ(parse(ARGC(missing_key), missing_key, &o, err), -1);
    CHECK(strstr(err, "--key-file") != NULL);
    const char *missing_lines[] = {"exo-sbc", "--key-file", "k", "--host", "1.2.3.4",
                                   "--spidev", CS4};
    CHECK_EQ(parse(ARGC(missing_lines), missing_lines, &o, err), -1);
    CHECK(strstr(err, "--solenoid-lines") != NULL);
    const char *no_value[] = {"exo-sbc", "--key-file"};
    CHECK_EQ(parse(ARGC(no_value), no_value, &o, err), -1);
    CHECK(strstr(err, "needs a value") != NULL);
    const char *same[] = {"exo-sbc", "--key-file", "k", "--host", "1.2.3.4", "--spidev", CS4,
                          "--solenoid-lines", "1,2", "--heartbeat-line", "5",
                          "--drivers-line", "5"};
    CHECK_EQ(parse(ARGC(same), same, &o, err), -1);
    CHECK(strstr(err, "both the heartbeat and the drivers readback line") != NULL);
    const char *daisy4[] = {"exo-sbc", "--key-file", "k", "--host", "1.2.3.4", "--bus",
                            "daisy-chain", "--spidev", CS4, "--solenoid-lines", "1,2"};
    CHECK_EQ(parse(ARGC(daisy4), daisy4, &o, err), -1);
    CHECK(strstr(err, "daisy-chain") != NULL);
}

static void key_parse(void)
{
    const char *hex = "000102030405060708090a0b0c0d0e0f101112131415161718191A1B1C1D1E1F\n";
    uint8_t key[SBC_KEY_BYTES];
    char err[128];
    CHECK_EQ(sbc_key_parse(hex, strlen(hex), key, err, sizeof err), 0);
    int ok = 1;
    for (int i = 0; i < SBC_KEY_BYTES; i++) {
        ok &= key[i] == i;
    }
    CHECK(ok);
    CHECK_EQ(sbc_key_parse(hex, 63, key, err, sizeof err), -1); /* 63 digits */
    CHECK(strstr(err, "64 hex digits") != NULL);
    char bad[80];
    strcpy(bad, hex);
    bad[10] = 'g';
    CHECK_EQ(sbc_key_parse(bad, strlen(bad), key, err, sizeof err), -1);
    CHECK(strstr(err, "character 11") != NULL);
    strcpy(bad, hex);
    bad[10] = ' ';
    CHECK_EQ(sbc_key_parse(bad, strlen(bad), key, err, sizeof err), -1);
    CHECK_EQ(sbc_key_parse("", 0, key, err, sizeof err), -1);
}

static void key_file_mode(void)
{
    char path[] = "/tmp/exo-sbc-test-keyXXXXXX";
    int fd = mkstemp(path);
    CHECK(fd >= 0);
    const char *hex = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f\n";
    CHECK_EQ(write(fd, hex, strlen(hex)), (long)strlen(hex));
    close(fd);
    uint8_t key[SBC_KEY_BYTES];
    char err[256];
    chmod(path, 0600);
    CHECK_EQ(sbc_key_load(path, key, err, sizeof err), 0);
    CHECK_EQ(key[31], 0x1Fu);
    chmod(path, 0640);
    CHECK_EQ(sbc_key_load(path, key, err, sizeof err), -1);
    CHECK(strstr(err, "readable by others") != NULL);
    unlink(path);
    CHECK_EQ(sbc_key_load(path, key, err, sizeof err), -1);
    CHECK(strstr(err, path) != NULL);
}

static void spi_frames(void)
{
    /* Read-angle command 0xFFFF and clear-error 0x4001 as the wire carries them. */
    const uint16_t frames[3] = {0xFFFF, 0x4001, 0x8000};
    uint8_t bytes[6];
    sbc_frames_to_bytes(frames, 3, bytes);
    const uint8_t want[6] = {0xFF, 0xFF, 0x40, 0x01, 0x80, 0x00};
    CHECK(memcmp(bytes, want, 6) == 0);
    uint16_t back[3];
    sbc_bytes_to_frames(bytes, 3, back);
    CHECK(memcmp(back, frames, sizeof frames) == 0);
}

static void identity(void)
{
    uint8_t id[SBC_UNIQUE_ID_BYTES];
    CHECK_EQ(sbc_parse_device_id("abc", id), 0); /* odd: a leading 0, then zero-padded */
    CHECK_EQ(id[0], 0x0Au);
    CHECK_EQ(id[1], 0xBCu);
    CHECK_EQ(id[2], 0u);
    CHECK_EQ(id[15], 0u);
    CHECK_EQ(sbc_parse_device_id("ff", id), 0);
    CHECK_EQ(id[0], 0xFFu);
    CHECK_EQ(id[1], 0u);
    CHECK_EQ(sbc_parse_device_id("", id), -1);
    CHECK_EQ(sbc_parse_device_id("0x12", id), -1);

    const char *mid = "0123456789abcdef0123456789abcdef\n";
    uint8_t machine[SBC_UNIQUE_ID_BYTES];
    CHECK_EQ(sbc_parse_machine_id(mid, strlen(mid), machine), 0);
    CHECK_EQ(machine[0], 0x01u);
    CHECK_EQ(machine[15], 0xEFu);
    CHECK_EQ(sbc_parse_machine_id(mid, 31, machine), -1);
    const char *zero = "00000000000000000000000000000000\n";
    CHECK_EQ(sbc_parse_machine_id(zero, strlen(zero), machine), -1);
    CHECK_EQ(sbc_parse_machine_id("uninitialized\n", 14, machine), -1);

    /* The id sent is a keyed hash of the machine-id, never the machine-id itself:
     * HMAC-SHA256(machine-id bytes, "exo-sbc unique id"), first 16 bytes (computed
     * separately with Python's hmac module). */
    CHECK_EQ(sbc_parse_machine_id(mid, strlen(mid), machine), 0);
    sbc_unique_id_from_machine_id(machine, id);
    const uint8_t want[SBC_UNIQUE_ID_BYTES] = {0xed, 0x3f, 0xa4, 0xf1, 0xfd, 0x72, 0x9b, 0xd0,
                                               0x72, 0x60, 0x8e, 0xcd, 0xe3, 0x59, 0x83, 0x58};
    CHECK_BYTES(id, want, sizeof want);

    char path[] = "/tmp/exo-sbc-machine-idXXXXXX";
    int fd = mkstemp(path);
    CHECK(fd >= 0);
    CHECK_EQ(write(fd, mid, strlen(mid)), (long)strlen(mid));
    close(fd);
    char err[256];
    uint8_t loaded[SBC_UNIQUE_ID_BYTES];
    CHECK_EQ(sbc_unique_id_load(path, loaded, err, sizeof err), 0);
    CHECK_BYTES(loaded, want, sizeof want);
    unlink(path);
    CHECK_EQ(sbc_unique_id_load(path, loaded, err, sizeof err), -1);
    CHECK(strstr(err, "--device-id") != NULL);

    /* The key id of the protocol's test key 00 01 .. 1f (Python's hmac module). */
    uint8_t key[32];
    for (unsigned i = 0; i < sizeof key; i++) {
        key[i] = (uint8_t)i;
    }
    char key_id[SBC_KEY_ID_HEX + 1];
    sbc_key_id(key, sizeof key, key_id);
    CHECK(strcmp(key_id, "8a26ef0ab1c027e8") == 0);
    CHECK(strlen(SBC_FIRMWARE_NAME) <= 16u);
}

/* A sender socket and the device's socket on loopback; returns the device's port. */
static uint16_t udp_pair(sbc_udp *dev, int *tx)
{
    char err[256];
    CHECK_EQ(sbc_udp_open(dev, 0x7F000001u, 0, err, sizeof err), 0);
    struct sockaddr_in a;
    socklen_t alen = sizeof a;
    CHECK_EQ(getsockname(dev->fd, (struct sockaddr *)&a, &alen), 0);
    *tx = socket(AF_INET, SOCK_DGRAM, 0);
    CHECK(*tx >= 0);
    return ntohs(a.sin_port);
}

static void send_to(int tx, uint16_t port, const uint8_t *data, size_t len)
{
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    a.sin_addr.s_addr = htonl(0x7F000001u);
    (void)sendto(tx, data, len, 0, (struct sockaddr *)&a, sizeof a);
}

static void udp_counts_every_datagram(void)
{
    sbc_udp dev;
    int tx;
    uint16_t port = udp_pair(&dev, &tx);
    uint8_t buf[256];
    exo_endpoint from = {0, 0};

    CHECK_EQ(sbc_udp_receive(&dev, buf, sizeof buf, &from), EXO_RX_NONE);
    /* An empty datagram is a datagram (length 0), not "nothing waiting". */
    send_to(tx, port, buf, 0);
    CHECK_EQ(sbc_udp_receive(&dev, buf, sizeof buf, &from), 0);
    CHECK_EQ(from.ip, 0x7F000001u);
    CHECK(from.port != 0u);
    CHECK_EQ(dev.empty, 1u);
    CHECK_EQ(sbc_udp_receive(&dev, buf, sizeof buf, &from), EXO_RX_NONE);
    /* Too long for the buffer: its true length, so the core counts it as `length`. */
    uint8_t big[300];
    memset(big, 0x45, sizeof big);
    send_to(tx, port, big, sizeof big);
    CHECK_EQ(sbc_udp_receive(&dev, buf, 100, &from), 300);

    /* A flood of empty datagrams, far beyond the capped buffer: every one is either
     * read or in the kernel's drop count (reported with the next datagram queued). */
    const unsigned flood = 5000u;
    for (unsigned i = 0; i < flood; i++) {
        send_to(tx, port, buf, 0);
    }
    uint64_t before = dev.received;
    while (sbc_udp_receive(&dev, buf, sizeof buf, &from) != EXO_RX_NONE) {
    }
    send_to(tx, port, buf, 1); /* one more, read after the drain: carries the drops */
    CHECK_EQ(sbc_udp_receive(&dev, buf, sizeof buf, &from), 1);
    uint64_t read_in_flood = dev.received - before;
    CHECK(dev.kernel_drops > 0u); /* the cap held: the buffer did not take them all */
    CHECK(read_in_flood < flood);
    CHECK_EQ(read_in_flood + dev.kernel_drops, flood + 1u);
    CHECK_EQ(dev.errors, 0u);
    close(tx);
    sbc_udp_close(&dev);
    CHECK_EQ(dev.fd, -1);
}

static void gpio_lines(void)
{
    char err[256];
    sbc_options o;
    memset(&o, 0, sizeof o);
    strcpy(o.gpiochip, "gpiochip0");
    o.line_left = 17;
    o.line_right = 27;
    o.has_heartbeat_line = 1;
    o.line_heartbeat = 22;
    o.has_drivers_line = 1;
    o.line_drivers = 23;

    fake_gpiod_reset();
    sbc_gpio g;
    CHECK_EQ(sbc_gpio_open(&g, &o, err, sizeof err), 0);
    CHECK(fake_lines[17].requested && fake_lines[17].output && fake_lines[17].value == 0);
    CHECK(fake_lines[22].requested && fake_lines[22].output && fake_lines[22].value == 0);
    CHECK(fake_lines[23].requested && !fake_lines[23].output);
    sbc_gpio_heartbeat(&g, 1);
    sbc_gpio_heartbeat(&g, 0);
    sbc_gpio_heartbeat(&g, 1);
    CHECK_EQ(fake_lines[22].edges, 3u);
    CHECK_EQ(fake_lines[17].edges, 0u); /* the heartbeat touches nothing else */
    fake_lines[23].input = 1;
    CHECK_EQ(sbc_gpio_drivers_status(&g), 0u);
    fake_lines[23].input = 0;
    CHECK_EQ(sbc_gpio_drivers_status(&g), EXO_STATUS_DRIVERS_OFF);
    fake_lines[23].fail_reads = 1; /* unreadable: not claimed as off, but counted */
    CHECK_EQ(sbc_gpio_drivers_status(&g), 0u);
    CHECK_EQ(g.drivers_read_errors, 1u);
    sbc_gpio_set(&g, 1, 0);
    CHECK_EQ(fake_lines[17].value, 1);
    sbc_gpio_close(&g);
    CHECK_EQ(fake_lines[17].value, 0); /* outputs low, then released */
    CHECK_EQ(fake_lines[22].value, 0);
    CHECK(!fake_lines[17].requested && !fake_lines[22].requested && !fake_lines[23].requested);

    /* Without the optional lines: no heartbeat, never DRIVERS_OFF. */
    fake_gpiod_reset();
    o.has_heartbeat_line = 0;
    o.has_drivers_line = 0;
    CHECK_EQ(sbc_gpio_open(&g, &o, err, sizeof err), 0);
    sbc_gpio_heartbeat(&g, 1);
    CHECK_EQ(fake_lines[22].edges, 0u);
    CHECK_EQ(sbc_gpio_drivers_status(&g), 0u);
    sbc_gpio_close(&g);

    /* A line that cannot be had: refused with its role named, nothing left requested. */
    fake_gpiod_reset();
    o.has_heartbeat_line = 1;
    o.line_heartbeat = FAKE_LINES + 1u;
    CHECK_EQ(sbc_gpio_open(&g, &o, err, sizeof err), -1);
    CHECK(strstr(err, "heartbeat") != NULL);
    CHECK(!fake_lines[17].requested && !fake_lines[27].requested);
}

int main(void)
{
    options_good();
    options_bad();
    key_parse();
    key_file_mode();
    spi_frames();
    identity();
    udp_counts_every_datagram();
    gpio_lines();
    printf("%d passed, %d failed\n", harness_passed, harness_failed);
    return harness_failed == 0 ? 0 : 1;
}
