/* gpio.c - GPIO registers (RM0410 "General-purpose I/Os"). */
#include "gpio.h"

void gpio_enable_port(uint32_t port)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOAEN << port;
    (void)RCC_AHB1ENR; /* read back: the clock is on before the port is touched */
}

static void set_mode(pin_t p, uint32_t mode)
{
    uint32_t shift = 2u * p.pin;
    GPIO_MODER(p.port) = (GPIO_MODER(p.port) & ~(3u << shift)) | (mode << shift);
}

void gpio_write(pin_t p, int high)
{
    GPIO_BSRR(p.port) = high ? (1u << p.pin) : (1u << (p.pin + 16u));
}

void gpio_output(pin_t p, int initial)
{
    gpio_enable_port(p.port);
    gpio_write(p, initial);
    GPIO_OTYPER(p.port) &= ~(1u << p.pin);
    GPIO_PUPDR(p.port) &= ~(3u << (2u * p.pin));
    set_mode(p, 1u);
}

void gpio_alternate(pin_t p, uint32_t af, int pull_up)
{
    gpio_enable_port(p.port);
    uint32_t shift = 4u * (p.pin & 7u);
    if (p.pin < 8u) {
        GPIO_AFRL(p.port) = (GPIO_AFRL(p.port) & ~(0xFu << shift)) | (af << shift);
    } else {
        GPIO_AFRH(p.port) = (GPIO_AFRH(p.port) & ~(0xFu << shift)) | (af << shift);
    }
    GPIO_OTYPER(p.port) &= ~(1u << p.pin);
    GPIO_OSPEEDR(p.port) |= 3u << (2u * p.pin);
    GPIO_PUPDR(p.port) = (GPIO_PUPDR(p.port) & ~(3u << (2u * p.pin))) |
                         ((pull_up ? 1u : 0u) << (2u * p.pin));
    set_mode(p, 2u);
}

void gpio_input_pull_down(pin_t p)
{
    gpio_enable_port(p.port);
    GPIO_PUPDR(p.port) = (GPIO_PUPDR(p.port) & ~(3u << (2u * p.pin))) | (2u << (2u * p.pin));
    set_mode(p, 0u);
}

int gpio_read(pin_t p)
{
    return (GPIO_IDR(p.port) >> p.pin) & 1u ? 1 : 0;
}
