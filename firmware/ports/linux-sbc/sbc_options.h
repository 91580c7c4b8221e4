/*
 * sbc_options.h - the command line of `exo-sbc`, the device core on a Linux
 * single-board computer. Parsing is kept apart from main() so that every refusal can
 * be tested without hardware.
 */
#ifndef SBC_OPTIONS_H
#define SBC_OPTIONS_H

#include <stddef.h>
#include <stdint.h>

#define SBC_MAX_SPIDEV 4
#define SBC_PATH_MAX 128
#define SBC_DEFAULT_PORT 47300
#define SBC_DEFAULT_SPI_HZ 1000000u  /* AS5048A allows 10 MHz; 1 MHz tolerates long leads */
#define SBC_MAX_SPI_HZ 10000000u
#define SBC_DEFAULT_PRIORITY 50
#define SBC_DEFAULT_WATCHDOG_S 1

typedef enum { SBC_BUS_CHIP_SELECTS = 0, SBC_BUS_DAISY_CHAIN = 1 } sbc_bus;

typedef struct {
    char key_file[SBC_PATH_MAX];
    uint32_t host_ip;          /* host byte order */
    uint32_t bind_ip;          /* 0: all addresses */
    uint16_t port;
    sbc_bus bus;
    unsigned n_spidev;         /* 4 with chip selects, 1 for a daisy chain */
    char spidev[SBC_MAX_SPIDEV][SBC_PATH_MAX];
    uint32_t spi_hz;
    unsigned spi_word_bits;    /* 8 (two bytes per frame, MSB first) or 16 */
    char gpiochip[SBC_PATH_MAX];
    unsigned line_left;        /* solenoid line offsets on gpiochip */
    unsigned line_right;
    int has_heartbeat_line;    /* --heartbeat-line given */
    unsigned line_heartbeat;   /* output to the heartbeat monostable */
    int has_drivers_line;      /* --drivers-line given */
    unsigned line_drivers;     /* input: the solenoid drivers' enable, read back */
    int has_device_id;         /* --device-id given (else /etc/machine-id) */
    uint8_t device_id[16];
    char watchdog[SBC_PATH_MAX]; /* "" when disabled with --watchdog none */
    unsigned watchdog_timeout_s;
    int realtime;
    int priority;
    double duration_s;         /* < 0: run until a signal */
} sbc_options;

/* 0: parsed; 1: --help was asked (print sbc_usage()); -1: an error, named in `err`. */
int sbc_options_parse(int argc, char **argv, sbc_options *o, char *err, size_t errlen);

const char *sbc_usage(void);

/* Dotted-quad IPv4 text to host byte order. 0 on success, -1 if malformed. */
int sbc_parse_ipv4(const char *text, uint32_t *out);

/* One line offset (0..4095). 0 on success, -1 if malformed. */
int sbc_parse_line(const char *text, unsigned *line);

/* "L,R" to two distinct line offsets. 0 on success, -1 if malformed or equal. */
int sbc_parse_lines(const char *text, unsigned *left, unsigned *right);

#endif /* SBC_OPTIONS_H */
