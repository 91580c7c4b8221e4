/*
 * exo_device.h - the portable device core's public interface (what a port calls).
 *
 * A port allocates one `exo_device` statically, fills an `exo_config` and an
 * `exo_board` (exo_board.h), calls exo_device_init once, then exo_device_poll in its
 * main loop, sleeping (or waiting for a datagram) for at most the microseconds poll
 * returns. exo_device_stop releases the solenoids before the port exits.
 *
 * The struct's fields are defined in exo_core_types.h (included below) so that a
 * port can allocate it without malloc; a port reads only `stats` and never writes a
 * field.
 */
#ifndef EXO_DEVICE_H
#define EXO_DEVICE_H

#include <stddef.h>
#include <stdint.h>

#include "exo_board.h"

#define EXO_KEY_BYTES 32
#define EXO_SAMPLE_PERIOD_US 10000u

/* How the four AS5048A encoders share the SPI bus. */
typedef enum {
    EXO_BUS_CHIP_SELECTS = 0, /* one chip select per encoder: chips 0..3 */
    EXO_BUS_DAISY_CHAIN = 1   /* one chip select, 4 x 16 bits shifted through */
} exo_bus_layout;

typedef struct {
    uint8_t key[EXO_KEY_BYTES]; /* the link key, shared with the host */
    uint32_t host_ip;           /* the only source address whose packets are acted on */
    uint32_t sample_period_us;  /* 0 means EXO_SAMPLE_PERIOD_US (100 Hz) */
    exo_bus_layout bus;
    /* Fault probe (0 or 1: off): send each sample period as this many samples, evenly
     * spaced, with honest device times: a device sending N times too fast. 1..100, as
     * the reference device's --rate-factor. */
    uint32_t rate_factor;
    /* The device identity its CHALLENGEs carry (protocol "CHALLENGE"), to which the
     * host binds hardware profiles: the processor's unique id or a serial number,
     * zero-padded; and the firmware name and version, printable ASCII, NUL-padded,
     * at most 16 characters, not empty (init refuses anything else). */
    uint8_t unique_id[16];
    char firmware[16];
} exo_config;

/* exo_device, exo_stats: defined in the core (see exo_core_types.h). */
#include "exo_core_types.h"

/* 0 on success; -1 if the board gave no entropy for the session number, lacks a
 * required function, or the config is out of range or has no valid firmware name
 * (then every later poll does nothing). Either way both solenoids are released;
 * WATCHDOG_RELEASED stays set until the first valid COMMAND. The core keeps no copy
 * of cfg->key (only its absorbed HMAC state); the port should wipe its own copy
 * (exo_secure_zero) once init has returned. */
int exo_device_init(exo_device *dev, const exo_board *board, const exo_config *cfg);

/* Handle every waiting datagram, run the watchdog, and build and send the sample if
 * it is due. Returns the microseconds until the next sample is due (0 if overdue):
 * the longest the port may wait before calling again. */
uint32_t exo_device_poll(exo_device *dev);

/* Release both solenoids (the port is about to exit or reset) and wipe the key
 * state; `stats` stay readable. */
void exo_device_stop(exo_device *dev);

#endif /* EXO_DEVICE_H */
