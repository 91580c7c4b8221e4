/* board.c - the exo_board functions on the Nucleo-F767ZI. */
#include "board.h"

#include "gpio.h"
#include "iwdg.h"
#include "rng.h"
#include "spi.h"
#include "timebase.h"
#include "wire.h"

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

/* The queue's count, not the length, says whether a datagram waits: an empty UDP
 * datagram is queued with length 0, and the core counts it (`short`). */
static long b_receive(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from)
{
    net_stack *net = (net_stack *)ctx;
    if (net->rx_count == 0u) {
        return EXO_RX_NONE;
    }
    return net_stack_receive(net, buf, cap, &from->ip, &from->port);
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

/* The heartbeat that keeps the external monostable, and so the solenoid drivers'
 * enable, on (docs/hardware-bringup-lab.md, "Hardware release (heartbeat)"). */
static void b_heartbeat(void *ctx, int level)
{
    (void)ctx;
    gpio_write(PIN_HEARTBEAT, level);
}

/* The drivers' enable read back: low means the monostable has let go (or the wire is
 * open: the pull-down reads that as off too). */
static uint32_t b_sense(void *ctx)
{
    (void)ctx;
    return gpio_read(PIN_DRIVERS_SENSE) ? 0u : EXO_STATUS_DRIVERS_OFF;
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
    b->sense_status = b_sense; /* DRIVERS_OFF only: no lock or supply sensing */
    b->heartbeat = b_heartbeat;
    b->truth = 0;        /* real hardware: no ground truth */
}

void board_solenoids_off(void)
{
    gpio_write(PIN_SOL_LEFT, 0);
    gpio_write(PIN_SOL_RIGHT, 0);
}

void board_pins_init(void)
{
    gpio_output(PIN_SOL_LEFT, 0);
    gpio_output(PIN_SOL_RIGHT, 0);
    /* Held still until the core's first toggle: the drivers stay off until then. */
    gpio_output(PIN_HEARTBEAT, 0);
    gpio_input_pull_down(PIN_DRIVERS_SENSE);
}

void board_unique_id(uint8_t out[16])
{
    /* 96 bits as three words at UID_BASE (RM0410 "Unique device ID register"), stored
     * little-endian in the order of their addresses, then four zero bytes. */
    for (uint32_t w = 0; w < 3u; w++) {
        uint32_t v = REG32(UID_BASE + 4u * w);
        for (uint32_t i = 0; i < 4u; i++) {
            out[4u * w + i] = (uint8_t)(v >> (8u * i));
        }
    }
    for (uint32_t i = 12u; i < 16u; i++) {
        out[i] = 0u;
    }
}
