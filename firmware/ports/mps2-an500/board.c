/*
 * board.c - the exo_board functions on QEMU's mps2-an500.
 *
 * Solenoid gates: the FPGA I/O's two user LEDs (bit 0 left, bit 1 right); the
 * samples report what the core drives. Heartbeat: MCC LED 0. Encoders: four emulated
 * AS5048A chips (the linux-sim port's model) holding fixed angles, so the core's
 * encoder code runs as on hardware and the samples carry valid counts. Entropy: the
 * emulation-only generator (entropy.h). No hardware watchdog and no status sensing:
 * QEMU models neither a solenoid driver nor its enable line.
 */
#include "board.h"

#include "as5048a_chip.h"
#include "entropy.h"
#include "mps2_regs.h"
#include "timebase.h"

/* The angles the emulated magnets present: the protocol's sample test vector. */
static const uint16_t ANGLES[4] = {3100u, 3105u, 12900u, 12890u};

static as5048a chips[4];
static uint32_t leds;

static uint64_t b_now_us(void *ctx)
{
    (void)ctx;
    return timebase_now_us();
}

static int b_spi(void *ctx, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n)
{
    (void)ctx;
    if (n == 0u || chip >= 4u || n > 4u - chip) {
        return -1;
    }
    for (size_t i = 0; i < n; i++) {
        rx[i] = as5048a_frame(&chips[chip + i], tx[i]);
    }
    return 0;
}

static void b_solenoids(void *ctx, int left, int right)
{
    (void)ctx;
    leds = (left ? 1u : 0u) | (right ? 2u : 0u);
    FPGAIO_LED0 = leds;
}

static int b_send(void *ctx, const uint8_t *data, size_t len, exo_endpoint to)
{
    return net_stack_send_udp((net_stack *)ctx, to.ip, to.port, data, len, timebase_now_us());
}

static long b_receive(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from)
{
    long n = net_stack_receive((net_stack *)ctx, buf, cap, &from->ip, &from->port);
    /* The stack never queues an empty datagram, so its 0 always means "none". */
    return n == 0 ? EXO_RX_NONE : n;
}

static void b_heartbeat(void *ctx, int level)
{
    (void)ctx;
    SCC_CFG1 = level ? 1u : 0u;
}

void board_fill(exo_board *b, net_stack *net)
{
    for (unsigned i = 0; i < 4u; i++) {
        as5048a_reset(&chips[i]);
        as5048a_set_magnet(&chips[i], ANGLES[i], 0);
    }
    *b = (exo_board){0};
    b->ctx = net;
    b->now_us = b_now_us;
    b->spi_transfer = b_spi;
    b->set_solenoids = b_solenoids;
    b->send = b_send;
    b->receive = b_receive;
    b->random_bytes = entropy_read;
    b->kick_watchdog = 0; /* QEMU's watchdog model is not a real one: none used */
    b->sense_status = 0;  /* no driver enable line to read: DRIVERS_OFF never set */
    b->truth = 0;
    b->heartbeat = b_heartbeat;
}

void board_solenoids_off(void)
{
    leds = 0u;
    FPGAIO_LED0 = 0u;
}
