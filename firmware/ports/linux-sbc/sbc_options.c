/* sbc_options.c - command-line parsing for exo-sbc. */
#include "sbc_options.h"

#include "sbc_identity.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *sbc_usage(void)
{
    return "usage: exo-sbc --key-file FILE --host IP --spidev PATH[,PATH,PATH,PATH]\n"
           "               --solenoid-lines LEFT,RIGHT [--heartbeat-line N]\n"
           "               [--drivers-line N] [--device-id HEX] [--gpiochip NAME] [--port N]\n"
           "               [--bind IP] [--bus chip-selects|daisy-chain] [--spi-hz N]\n"
           "               [--spi-word 8|16] [--watchdog PATH|none] [--watchdog-timeout S]\n"
           "               [--priority N] [--no-realtime] [--duration S]\n"
           "\n"
           "  --key-file FILE       the link key: the host's var/device.key (mode 0600)\n"
           "  --host IP             the host (ExoStudy worker); packets from any other IP\n"
           "                        are ignored\n"
           "  --port N              UDP port to listen on (default 47300)\n"
           "  --bind IP             local address to listen on (default all)\n"
           "  --bus LAYOUT          chip-selects: four --spidev paths, left output, left\n"
           "                        cam, right output, right cam (default); daisy-chain:\n"
           "                        one path\n"
           "  --spidev PATHS        /dev/spidevB.C, comma-separated\n"
           "  --spi-hz N            SPI clock (default 1000000, at most 10000000)\n"
           "  --spi-word 8|16       bits per SPI word: 8 sends each frame as two bytes,\n"
           "                        MSB first (works on every controller; default)\n"
           "  --gpiochip NAME       gpiochip name, number or path (default gpiochip0)\n"
           "  --solenoid-lines L,R  line offsets driving the left and right solenoid\n"
           "                        MOSFET gates (requested as outputs, initially low)\n"
           "  --heartbeat-line N    output toggled once per sample period: the trigger of\n"
           "                        the monostable that holds the drivers' enable (the\n"
           "                        hardware release); without it, a warning\n"
           "  --drivers-line N      input: the drivers' enable read back; low is reported\n"
           "                        as DRIVERS_OFF\n"
           "  --device-id HEX       the board's serial number, 1..32 hex digits, sent as\n"
           "                        its unique id (default: derived from /etc/machine-id)\n"
           "  --watchdog PATH|none  kernel watchdog device (default /dev/watchdog; skipped\n"
           "                        with a warning if absent)\n"
           "  --watchdog-timeout S  seconds without a kick before the board resets\n"
           "                        (default 1)\n"
           "  --priority N          SCHED_FIFO priority 1..99 (default 50)\n"
           "  --no-realtime         run without SCHED_FIFO and mlockall (bench use only)\n"
           "  --duration S          stop after S seconds (default: run until SIGINT/TERM)\n";
}

int sbc_parse_ipv4(const char *text, uint32_t *out)
{
    uint32_t ip = 0;
    const char *p = text;
    for (int part = 0; part < 4; part++) {
        if (*p < '0' || *p > '9') {
            return -1;
        }
        unsigned v = 0;
        int digits = 0;
        while (*p >= '0' && *p <= '9') {
            v = v * 10u + (unsigned)(*p - '0');
            if (++digits > 3 || v > 255u) {
                return -1;
            }
            p++;
        }
        if (digits > 1 && p[-digits] == '0') {
            return -1; /* leading zeros read as octal by some tools: refuse, be unambiguous */
        }
        ip = ip << 8 | v;
        if (part < 3) {
            if (*p != '.') {
                return -1;
            }
            p++;
        }
    }
    if (*p != '\0') {
        return -1;
    }
    *out = ip;
    return 0;
}

static int parse_uint(const char *text, unsigned long max, unsigned long *out)
{
    if (text[0] < '0' || text[0] > '9') {
        return -1;
    }
    char *end;
    errno = 0;
    unsigned long v = strtoul(text, &end, 10);
    if (errno != 0 || *end != '\0' || v > max) {
        return -1;
    }
    *out = v;
    return 0;
}

int sbc_parse_line(const char *text, unsigned *line)
{
    unsigned long v;
    if (parse_uint(text, 4095, &v) != 0) {
        return -1;
    }
    *line = (unsigned)v;
    return 0;
}

int sbc_parse_lines(const char *text, unsigned *left, unsigned *right)
{
    char buf[64];
    if (strlen(text) >= sizeof buf) {
        return -1;
    }
    strcpy(buf, text);
    char *comma = strchr(buf, ',');
    if (comma == NULL) {
        return -1;
    }
    *comma = '\0';
    unsigned long l, r;
    if (parse_uint(buf, 4095, &l) != 0 || parse_uint(comma + 1, 4095, &r) != 0 || l == r) {
        return -1;
    }
    *left = (unsigned)l;
    *right = (unsigned)r;
    return 0;
}

static int copy_path(char *dst, const char *src)
{
    size_t n = strlen(src);
    if (n == 0 || n >= SBC_PATH_MAX) {
        return -1;
    }
    memcpy(dst, src, n + 1);
    return 0;
}

static int parse_spidev(sbc_options *o, const char *text)
{
    const char *p = text;
    o->n_spidev = 0;
    while (1) {
        const char *comma = strchr(p, ',');
        size_t n = comma ? (size_t)(comma - p) : strlen(p);
        if (o->n_spidev == SBC_MAX_SPIDEV || n == 0 || n >= SBC_PATH_MAX) {
            return -1;
        }
        memcpy(o->spidev[o->n_spidev], p, n);
        o->spidev[o->n_spidev][n] = '\0';
        o->n_spidev++;
        if (comma == NULL) {
            return 0;
        }
        p = comma + 1;
    }
}

#define FAIL(...)                                                                          \
    do {                                                                                   \
        snprintf(err, errlen, __VA_ARGS__);                                                \
        return -1;                                                                         \
    } while (0)

int sbc_options_parse(int argc, char **argv, sbc_options *o, char *err, size_t errlen)
{
    memset(o, 0, sizeof *o);
    o->port = SBC_DEFAULT_PORT;
    o->spi_hz = SBC_DEFAULT_SPI_HZ;
    o->spi_word_bits = 8;
    strcpy(o->gpiochip, "gpiochip0");
    strcpy(o->watchdog, "/dev/watchdog");
    o->watchdog_timeout_s = SBC_DEFAULT_WATCHDOG_S;
    o->realtime = 1;
    o->priority = SBC_DEFAULT_PRIORITY;
    o->duration_s = -1.0;
    int have_host = 0, have_lines = 0;

    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        if (strcmp(arg, "--help") == 0 || strcmp(arg, "-h") == 0) {
            return 1;
        }
        if (strcmp(arg, "--no-realtime") == 0) {
            o->realtime = 0;
            continue;
        }
        if (strncmp(arg, "--", 2) != 0) {
            FAIL("unexpected argument '%s'", arg);
        }
        /* Every other option takes a value: "--name value" or "--name=value". */
        char name[32];
        const char *value;
        const char *eq = strchr(arg, '=');
        if (eq != NULL) {
            size_t n = (size_t)(eq - arg);
            if (n >= sizeof name) {
                FAIL("unknown option '%s'", arg);
            }
            memcpy(name, arg, n);
            name[n] = '\0';
            value = eq + 1;
        } else {
            if (strlen(arg) >= sizeof name) {
                FAIL("unknown option '%s'", arg);
            }
            strcpy(name, arg);
            if (i + 1 >= argc) {
                FAIL("%s needs a value", arg);
            }
            value = argv[++i];
        }
        unsigned long v;
        if (strcmp(name, "--key-file") == 0) {
            if (copy_path(o->key_file, value) != 0) {
                FAIL("--key-file: empty or longer than %d characters", SBC_PATH_MAX - 1);
            }
        } else if (strcmp(name, "--host") == 0) {
            if (sbc_parse_ipv4(value, &o->host_ip) != 0 || o->host_ip == 0) {
                FAIL("--host: '%s' is not an IPv4 address like 192.168.50.1", value);
            }
            have_host = 1;
        } else if (strcmp(name, "--bind") == 0) {
            if (sbc_parse_ipv4(value, &o->bind_ip) != 0) {
                FAIL("--bind: '%s' is not an IPv4 address", value);
            }
        } else if (strcmp(name, "--port") == 0) {
            if (parse_uint(value, 65535, &v) != 0 || v == 0) {
                FAIL("--port: '%s' is not a port number 1..65535", value);
            }
            o->port = (uint16_t)v;
        } else if (strcmp(name, "--bus") == 0) {
            if (strcmp(value, "chip-selects") == 0) {
                o->bus = SBC_BUS_CHIP_SELECTS;
            } else if (strcmp(value, "daisy-chain") == 0) {
                o->bus = SBC_BUS_DAISY_CHAIN;
            } else {
                FAIL("--bus: '%s' is neither chip-selects nor daisy-chain", value);
            }
        } else if (strcmp(name, "--spidev") == 0) {
            if (parse_spidev(o, value) != 0) {
                FAIL("--spidev: '%s' is not 1 to 4 comma-separated paths", value);
            }
        } else if (strcmp(name, "--spi-hz") == 0) {
            if (parse_uint(value, SBC_MAX_SPI_HZ, &v) != 0 || v < 10000u) {
                FAIL("--spi-hz: '%s' is not 10000..%u (the AS5048A's limit)", value,
                     SBC_MAX_SPI_HZ);
            }
            o->spi_hz = (uint32_t)v;
        } else if (strcmp(name, "--spi-word") == 0) {
            if (strcmp(value, "8") == 0) {
                o->spi_word_bits = 8;
            } else if (strcmp(value, "16") == 0) {
                o->spi_word_bits = 16;
            } else {
                FAIL("--spi-word: '%s' is neither 8 nor 16", value);
            }
        } else if (strcmp(name, "--gpiochip") == 0) {
            if (copy_path(o->gpiochip, value) != 0) {
                FAIL("--gpiochip: empty or too long");
            }
        } else if (strcmp(name, "--solenoid-lines") == 0) {
            if (sbc_parse_lines(value, &o->line_left, &o->line_right) != 0) {
                FAIL("--solenoid-lines: '%s' is not two different line offsets LEFT,RIGHT",
                     value);
            }
            have_lines = 1;
        } else if (strcmp(name, "--heartbeat-line") == 0) {
            if (sbc_parse_line(value, &o->line_heartbeat) != 0) {
                FAIL("--heartbeat-line: '%s' is not a line offset 0..4095", value);
            }
            o->has_heartbeat_line = 1;
        } else if (strcmp(name, "--drivers-line") == 0) {
            if (sbc_parse_line(value, &o->line_drivers) != 0) {
                FAIL("--drivers-line: '%s' is not a line offset 0..4095", value);
            }
            o->has_drivers_line = 1;
        } else if (strcmp(name, "--device-id") == 0) {
            if (sbc_parse_device_id(value, o->device_id) != 0) {
                FAIL("--device-id: '%s' is not 1 to 32 hexadecimal digits", value);
            }
            o->has_device_id = 1;
        } else if (strcmp(name, "--watchdog") == 0) {
            if (strcmp(value, "none") == 0) {
                o->watchdog[0] = '\0';
            } else if (copy_path(o->watchdog, value) != 0) {
                FAIL("--watchdog: empty or too long");
            }
        } else if (strcmp(name, "--watchdog-timeout") == 0) {
            if (parse_uint(value, 60, &v) != 0 || v == 0) {
                FAIL("--watchdog-timeout: '%s' is not 1..60 seconds", value);
            }
            o->watchdog_timeout_s = (unsigned)v;
        } else if (strcmp(name, "--priority") == 0) {
            if (parse_uint(value, 99, &v) != 0 || v == 0) {
                FAIL("--priority: '%s' is not 1..99", value);
            }
            o->priority = (int)v;
        } else if (strcmp(name, "--duration") == 0) {
            char *end;
            double d = strtod(value, &end);
            if (*end != '\0' || end == value || !(d > 0.0) || d > 1e7) {
                FAIL("--duration: '%s' is not a positive number of seconds", value);
            }
            o->duration_s = d;
        } else {
            FAIL("unknown option '%s'", name);
        }
    }
    if (o->key_file[0] == '\0') {
        FAIL("--key-file is required (the host's var/device.key)");
    }
    if (!have_host) {
        FAIL("--host is required (the IP of the ExoStudy host)");
    }
    if (o->n_spidev == 0) {
        FAIL("--spidev is required");
    }
    if (o->bus == SBC_BUS_CHIP_SELECTS && o->n_spidev != 4) {
        FAIL("--bus chip-selects needs 4 --spidev paths (left output, left cam, right "
             "output, right cam), got %u",
             o->n_spidev);
    }
    if (o->bus == SBC_BUS_DAISY_CHAIN && o->n_spidev != 1) {
        FAIL("--bus daisy-chain needs exactly 1 --spidev path, got %u", o->n_spidev);
    }
    if (!have_lines) {
        FAIL("--solenoid-lines is required (the two gate lines, LEFT,RIGHT)");
    }
    /* Every line once: two roles on one line would drive an output we read, or pulse
     * a solenoid with the heartbeat. */
    unsigned used[4] = {o->line_left, o->line_right, o->line_heartbeat, o->line_drivers};
    int given[4] = {1, 1, o->has_heartbeat_line, o->has_drivers_line};
    static const char *const role[4] = {"left solenoid", "right solenoid", "heartbeat",
                                        "drivers readback"};
    for (int i = 2; i < 4; i++) {
        for (int j = 0; j < i; j++) {
            if (given[i] && given[j] && used[i] == used[j]) {
                FAIL("line %u is both the %s and the %s line (--solenoid-lines, "
                     "--heartbeat-line and --drivers-line must all differ)",
                     used[i], role[j], role[i]);
            }
        }
    }
    return 0;
}
