/*
 * gpio.h - pin set-up and output writes.
 */
#ifndef GPIO_H
#define GPIO_H

#include "pins.h"

void gpio_enable_port(uint32_t port);
/* Push-pull output, driven `initial` before the pin leaves its reset (input) mode, so
 * that a solenoid gate is never driven high by accident on the way. */
void gpio_output(pin_t p, int initial);
/* Alternate function `af`, very high speed, optional pull-up (MISO idles defined). */
void gpio_alternate(pin_t p, uint32_t af, int pull_up);
void gpio_write(pin_t p, int high);

#endif /* GPIO_H */
