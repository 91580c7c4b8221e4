/*
 * main.c - the ExoStudy device firmware on an STM32 Nucleo-F767ZI.
 *
 * Start-up puts the solenoid gates and the heartbeat low before anything else (the
 * solenoid drivers stay disabled until the core's first heartbeat edge), then the clock,
 * the microsecond timer, the provisioning block (key and addresses), the encoder bus,
 * the RNG and Ethernet, starts the device core and, last, the independent watchdog.
 * Any failure on the way stops with both solenoids off and the red LED blinking a
 * count (docs/hardware-bringup-lab.md lists them).
 *
 * The loop is polled, with no interrupts: receive frames into the network stack, let
 * the core handle datagrams and send the sample when due, check the PHY four times a
 * second. The core kicks the watchdog and toggles the heartbeat once per sample period.
 * The key is wiped from every buffer of this file with exo_secure_zero (the core's,
 * hmac.h), which the optimiser may not remove as it may a memset of a dead buffer.
 */
#include <stdint.h>

#include "board.h"
#include "clock.h"
#include "console.h"
#include "eth_mac.h"
#include "exo_device.h"
#include "gpio.h"
#include "hmac.h"
#include "iwdg.h"
#include "net/net_stack.h"
#include "prov.h"
#include "rng.h"
#include "spi.h"
#include "timebase.h"

#ifndef NUCLEO_BUS_DAISY_CHAIN
#define NUCLEO_BUS_DAISY_CHAIN 0 /* build with -DNUCLEO_BUS_DAISY_CHAIN=1 for a chain */
#endif

#ifndef EXO_FIRMWARE_VERSION
#define EXO_FIRMWARE_VERSION "dev" /* the Makefile passes the source tree's git revision */
#endif

#define LINK_CHECK_US 250000u
#define LED_BLINK_US 500000u
#define FIRMWARE_NAME "exo-nucleo 3" /* the CHALLENGE's firmware field (<= 16 chars) */
#define KEY_ID_BYTES 8u
typedef char firmware_name_fits[sizeof FIRMWARE_NAME - 1u <= 16u ? 1 : -1];

/* Blink counts of the red LED for each start-up failure. */
enum {
    FAULT_CLOCK = 1,     /* the PLL did not lock */
    FAULT_PROVISION = 2, /* no valid provisioning block: write one (no retry) */
    FAULT_ETHERNET = 3,  /* no PHY or no 50 MHz reference clock */
    FAULT_CORE = 4       /* the core refused to start (no entropy) */
};

extern const uint8_t _prov_start[];

static exo_device dev;
static net_stack net;

static void busy_wait_ms(uint32_t ms)
{
    /* Counts cycles, so valid on the 16 MHz HSI too (it is then just longer). */
    while (ms--) {
        clock_delay_cycles(CLOCK_HCLK_HZ / 1000u);
    }
}

/* Solenoids off, blink `count` times every 2 s. A missing provisioning block needs a
 * person, so it blinks forever; anything else resets after about 5 s to try again. */
static void halt(int count, const char *why)
{
    board_solenoids_off();
    gpio_write(PIN_HEARTBEAT, 0); /* no more edges: the monostable lets go */
    console_puts("STOPPED, solenoids off: ");
    console_puts(why);
    console_puts(count == FAULT_PROVISION ? "\n" : " (resetting in 5 s)\n");
    for (unsigned round = 0;; round++) {
        for (int i = 0; i < count; i++) {
            gpio_write(PIN_LED_RED, 1);
            busy_wait_ms(200);
            gpio_write(PIN_LED_RED, 0);
            busy_wait_ms(200);
        }
        busy_wait_ms(2000);
        if (count != FAULT_PROVISION && round >= 2u) {
            SCB_AIRCR = SCB_AIRCR_RESET;
        }
    }
}

int main(void)
{
    board_pins_init();
    gpio_output(PIN_LED_GREEN, 0);
    gpio_output(PIN_LED_BLUE, 0);
    gpio_output(PIN_LED_RED, 0);

    clock_source clock = clock_init();
    /* If the PLL failed the chip runs on its 16 MHz internal oscillator, APB1 undivided. */
    console_init(clock == CLOCK_FAILED ? 16000000u : CLOCK_PCLK1_HZ);
    console_puts("\nExoStudy device firmware " EXO_FIRMWARE_VERSION
                 ", nucleo-f767zi, protocol 3\n");
    if (clock == CLOCK_FAILED) {
        halt(FAULT_CLOCK, "the PLL did not lock");
    }
    console_puts(clock == CLOCK_FROM_HSE ? "clock: 96 MHz from the ST-LINK's 8 MHz\n"
                                         : "clock: 96 MHz from the internal 16 MHz (HSE absent)\n");
    timebase_init();
    int watchdog_reset = iwdg_caused_reset();
    if (watchdog_reset) {
        console_puts("reset: by the independent watchdog (the loop had stopped)\n");
    }

    prov_block prov;
    prov_error perr = prov_parse(_prov_start, PROV_SIZE, &prov);
    if (perr != PROV_OK) {
        halt(FAULT_PROVISION, prov_error_name(perr));
    }
    /* Key id: the first 8 bytes of HMAC-SHA256(key, "exostudy key id"), as the host's
     * console shows it (docs/device-protocol.md). Not secret; the keyed state is. */
    static const uint8_t key_id_label[] = "exostudy key id";
    exo_hmac_key id_key;
    uint8_t key_id[EXO_SHA256_BYTES];
    exo_hmac_set_key(&id_key, prov.key, sizeof prov.key);
    exo_hmac_sha256(&id_key, key_id_label, sizeof key_id_label - 1u, 0, 0u, key_id);
    exo_secure_zero(&id_key, sizeof id_key);
    uint8_t unique_id[16];
    board_unique_id(unique_id);
    console_puts("device ");
    console_ipv4(prov.device_ip);
    console_puts(" port ");
    console_uint(prov.udp_port);
    console_puts(", host ");
    console_ipv4(prov.host_ip);
    console_puts(", mac ");
    for (unsigned i = 0; i < 6u; i++) {
        console_hex(&prov.mac[i], 1);
        console_puts(i < 5u ? ":" : "");
    }
    console_puts(", key id ");
    console_hex(key_id, KEY_ID_BYTES);
    console_puts(", unique id ");
    console_hex(unique_id, 12);
    console_puts(NUCLEO_BUS_DAISY_CHAIN ? ", encoders: daisy chain\n"
                                        : ", encoders: four chip selects\n");

    spi_init();
    rng_init();
    if (eth_init(prov.mac) != 0) {
        halt(FAULT_ETHERNET, "no Ethernet PHY or no 50 MHz reference clock");
    }
    net_config ncfg = {.ip = prov.device_ip,
                       .netmask = prov.netmask,
                       .udp_port = prov.udp_port,
                       .peer_ip = prov.host_ip};
    for (unsigned i = 0; i < 6u; i++) {
        ncfg.mac[i] = prov.mac[i];
    }
    net_stack_init(&net, &ncfg, eth_send, 0);

    exo_board board;
    board_fill(&board, &net);
    exo_config cfg = {0};
    for (unsigned i = 0; i < EXO_KEY_BYTES; i++) {
        cfg.key[i] = prov.key[i];
    }
    cfg.host_ip = prov.host_ip;
    cfg.sample_period_us = EXO_SAMPLE_PERIOD_US;
    cfg.bus = NUCLEO_BUS_DAISY_CHAIN ? EXO_BUS_DAISY_CHAIN : EXO_BUS_CHIP_SELECTS;
    cfg.rate_factor = 1;
    for (unsigned i = 0; i < sizeof cfg.unique_id; i++) {
        cfg.unique_id[i] = unique_id[i];
    }
    for (unsigned i = 0; i < sizeof FIRMWARE_NAME - 1u; i++) {
        cfg.firmware[i] = FIRMWARE_NAME[i]; /* the rest stays NUL (cfg = {0}) */
    }
    int rc = exo_device_init(&dev, &board, &cfg);
    /* The core keeps only its absorbed HMAC state: wipe both copies of the key here. */
    exo_secure_zero(cfg.key, sizeof cfg.key);
    exo_secure_zero(&prov, sizeof prov);
    if (rc != 0) {
        halt(FAULT_CORE, "the device core refused to start (no entropy from the RNG)");
    }

    iwdg_start();
    console_puts("running: waiting for the host\n");

    uint64_t now = timebase_now_us();
    uint64_t due = now;
    uint64_t next_link = now;
    uint64_t next_blink = now;
    uint64_t red_until = watchdog_reset ? now + 2000000u : 0u; /* "the watchdog fired" */
    int green = 0;
    uint32_t lost_wraps_told = 0u;
    gpio_write(PIN_LED_RED, watchdog_reset);
    for (;;) {
        now = timebase_now_us();
        const uint8_t *frame;
        size_t n;
        /* At most one ring's worth per pass, so a flood of frames cannot starve the
         * sample schedule; the rest wait in the DMA ring (or are dropped by the MAC). */
        for (unsigned i = 0; i < ETH_RX_BUFS && (n = eth_rx_take(&frame)) > 0u; i++) {
            net_stack_input(&net, frame, n, now);
            eth_rx_release();
        }
        if (now >= next_link) {
            gpio_write(PIN_LED_BLUE, eth_link_poll());
            next_link = now + LINK_CHECK_US;
        }
        if (net.rx_count > 0u || now >= due) {
            uint32_t wait = exo_device_poll(&dev);
            due = timebase_now_us() + wait;
        }
        if (timebase_state()->lost_wraps != lost_wraps_told) {
            /* The loop stood still for more than 71.6 minutes, which the watchdog
             * should have prevented; the time base measured it right anyway, so the
             * core saw the whole stall (watchdog released, old commands stale). */
            lost_wraps_told = timebase_state()->lost_wraps;
            console_puts("timebase: a stall longer than the 32-bit timer's wrap, measured\n");
        }
        if (now >= next_blink) {
            green = !green;
            gpio_write(PIN_LED_GREEN, green);
            next_blink = now + LED_BLINK_US;
            if (red_until != 0u && now >= red_until) {
                gpio_write(PIN_LED_RED, 0);
                red_until = 0u;
            }
        }
    }
}
