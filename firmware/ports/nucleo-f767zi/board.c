/* board.c - the exo_board functions on the Nucleo-F767ZI. */
#include "board.h"

#include "gpio.h"
#include "iwdg.h"
#include "rng.h"
#include "spi.h"
#include "timebase.h"

static uint64_t b_now_us(void *ctx)
{
    (void)ctx;
    return timebase_now_us();
}

static int b_spi(void *ctx, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n)
{
    (void)ctx;
    return spi_transfer(chip, tx, rx, n);
}

static void b_solenoids(void *ctx, int left, int right)
{
    (void)ctx;
    gpio_write(PIN_SOL_LEFT, left);
    gpio_write(PIN_SOL_RIGHT, right);
}

static int b_send(void *ctx, const uint8_t *data, size_t len, exo_endpoint to)
{
    return net_stack_send_udp((net_stack *)ctx, to.ip, to.port, data, len, timebase_now_us());
}

static long b_receive(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from)
{
    return net_stack_receive((net_stack *)ctx, buf, cap, &from->ip, &from->port);
}

static int b_random(void *ctx, uint8_t *out, size_t n)
{
    (void)ctx;
    return rng_read(out, n);
}

static void b_kick(void *ctx)
{
    (void)ctx;
    iwdg_kick();
}

void board_fill(exo_board *b, net_stack *net)
{
    *b = (exo_board){0};
    b->ctx = net;
    b->now_us = b_now_us;
    b->spi_transfer = b_spi;
    b->set_solenoids = b_solenoids;
    b->send = b_send;
    b->receive = b_receive;
    b->random_bytes = b_random;
    b->kick_watchdog = b_kick;
    b->sense_status = 0; /* no lock or supply sensing on this wiring */
    b->truth = 0;        /* real hardware: no ground truth */
}

void board_solenoids_off(void)
{
    gpio_write(PIN_SOL_LEFT, 0);
    gpio_write(PIN_SOL_RIGHT, 0);
}
