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
/* Input with the internal pull-down (so an open wire reads 0). */
void gpio_input_pull_down(pin_t p);
/* 1 if the pin reads high, else 0. */
int gpio_read(pin_t p);

#endif /* GPIO_H */
