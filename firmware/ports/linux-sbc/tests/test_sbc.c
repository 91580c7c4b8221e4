/* exo-sbc's pure helpers: options, key file, SPI byte framing. */
#include <fcntl.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../../test-harness/harness.h"

#include "../sbc_key.h"
#include "../sbc_options.h"
#include "../sbc_spi_frames.h"

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

int main(void)
{
    options_good();
    options_bad();
    key_parse();
    key_file_mode();
    spi_frames();
    printf("%d passed, %d failed\n", harness_passed, harness_failed);
    return harness_failed == 0 ? 0 : 1;
}
