/*
 * sbc_gpio.h - the GPIO lines through libgpiod (v1 API, Debian 12's libgpiod 1.6):
 *   - the two solenoid gate lines, requested as outputs with initial value 0, so the
 *     solenoids stay off from the moment this program owns the lines (the gate
 *     pull-down keeps them off before that and after it exits);
 *   - optionally the heartbeat line, an output toggled by the core once per sample
 *     period, which keeps the external retriggerable monostable holding the solenoid
 *     drivers' enable (docs/hardware-bringup-lab.md, "Hardware release (heartbeat)");
 *     requested at 0, so the drivers stay off until the core's first edge;
 *   - optionally the drivers' enable line read back (input): read low, the sample
 *     reports DRIVERS_OFF. Without it DRIVERS_OFF is never reported, and the bring-up
 *     step that times the hardware release fails, as it should.
 */
#ifndef SBC_GPIO_H
#define SBC_GPIO_H

#include <stddef.h>
#include <stdint.h>

#include "sbc_options.h"

struct gpiod_chip;
struct gpiod_line;

typedef struct {
    struct gpiod_chip *chip;
    struct gpiod_line *left;
    struct gpiod_line *right;
    struct gpiod_line *heartbeat;    /* NULL without --heartbeat-line */
    struct gpiod_line *drivers;      /* NULL without --drivers-line */
    uint64_t drivers_read_errors;    /* readback failed (then not reported as off) */
} sbc_gpio;

int sbc_gpio_open(sbc_gpio *g, const sbc_options *o, char *err, size_t errlen);
void sbc_gpio_set(sbc_gpio *g, int left, int right);
/* Drive the heartbeat line (no-op without one). */
void sbc_gpio_heartbeat(sbc_gpio *g, int level);
/* EXO_STATUS_DRIVERS_OFF if the enable line reads low, else 0 (also without one). */
uint32_t sbc_gpio_drivers_status(sbc_gpio *g);
/* Drive the outputs low, then release every line and close the chip. */
void sbc_gpio_close(sbc_gpio *g);

#endif /* SBC_GPIO_H */
