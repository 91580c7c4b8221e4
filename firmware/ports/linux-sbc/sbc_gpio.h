/*
 * sbc_gpio.h - the two solenoid gate lines through libgpiod (v1 API, Debian 12's
 * libgpiod 1.6). Requested as outputs with initial value 0, so the solenoids stay off
 * from the moment this program owns the lines; the gate pull-down keeps them off
 * before that and after it exits.
 */
#ifndef SBC_GPIO_H
#define SBC_GPIO_H

#include <stddef.h>

#include "sbc_options.h"

struct gpiod_chip;
struct gpiod_line;

typedef struct {
    struct gpiod_chip *chip;
    struct gpiod_line *left;
    struct gpiod_line *right;
} sbc_gpio;

int sbc_gpio_open(sbc_gpio *g, const sbc_options *o, char *err, size_t errlen);
void sbc_gpio_set(sbc_gpio *g, int left, int right);
/* Drive both lines low, then release them and close the chip. */
void sbc_gpio_close(sbc_gpio *g);

#endif /* SBC_GPIO_H */
