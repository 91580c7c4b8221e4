/*
 * main.c - the ExoStudy device firmware on QEMU's mps2-an500 (a Cortex-M7 with a
 * LAN9118): the portable device core and the Nucleo port's network stack on an
 * emulated board, so that `make test` can run the firmware's own code paths (the
 * cross-compiled core, the IPv4/UDP stack, an Ethernet driver) against the host.
 *
 * EMULATION ONLY: the key, addresses, unique id and the boot seed for session numbers
 * come from a block that the emulator's launcher loads into memory (emu_prov.h). Any
 * start-up failure stops with both solenoid outputs off and a line on the console.
 *
 * The loop is polled: take frames from the LAN9118 into the network stack, let the
 * core handle datagrams and send the sample when due. Between events it waits for an
 * interrupt (SysTick every 1 ms, or a received frame), so the emulator does not spin
 * a host core.
 */
#include <stdint.h>

#include "board.h"
#include "console.h"
#include "emu_prov.h"
#include "entropy.h"
#include "exo_device.h"
#include "hmac.h"
#include "lan9118.h"
#include "mps2_regs.h"
#include "net_stack.h"
#include "timebase.h"
#include "wire.h"

#ifndef EXO_FIRMWARE_VERSION
#define EXO_FIRMWARE_VERSION "dev" /* the Makefile passes the source tree's git revision */
#endif

#define FIRMWARE_NAME "exo-mps2 3" /* the CHALLENGE's firmware field */
#define RX_FRAMES_PER_PASS 16u /* so that a flood cannot starve the sample schedule */
#define REPORT_US 5000000u

#define SYST_CSR REG32(0xE000E010u)
#define SYST_RVR REG32(0xE000E014u)
#define SYST_CVR REG32(0xE000E018u)
#define NVIC_ISER0 REG32(0xE000E100u)
#define LAN9118_IRQ 13u
#define LAN_IRQ_CFG REG32(LAN9118_BASE + 0x54u)
#define LAN_INT_EN REG32(LAN9118_BASE + 0x5Cu)
#define LAN_RX_FIFO_INF REG32(LAN9118_BASE + 0x7Cu)

extern const uint8_t _emu_block[];

static exo_device dev;
static net_stack net;
static uint8_t frame[NET_ETH_MAX + 4u];

/* Overwrite through a volatile pointer: a store the compiler may not drop. */
static void wipe(volatile uint8_t *p, size_t n)
{
    while (n--) {
        *p++ = 0u;
    }
}

static void halt(const char *why)
{
    board_solenoids_off();
    console_puts("STOPPED, solenoids off: ");
    console_puts(why);
    console_puts("\n");
    for (;;) {
        __asm__ volatile("wfi");
    }
}

/* Wake-ups for the wait in the loop: SysTick each 1 ms, the LAN9118 on a frame. */
static void wakeups_init(void)
{
    SYST_RVR = MPS2_SYSCLK_HZ / 1000u - 1u;
    SYST_CVR = 0u;
    SYST_CSR = 7u; /* processor clock, interrupt, enable */
    LAN_INT_EN = 1u << 3;                          /* RSFL: a status word is waiting */
    LAN_IRQ_CFG = (1u << 8) | (1u << 4) | 1u;      /* enabled, active high, push-pull */
    NVIC_ISER0 = 1u << LAN9118_IRQ;
}

static void print_report(void)
{
    console_puts("net: frames in ");
    console_uint(net.stats.frames_in);
    console_puts(" out ");
    console_uint(net.stats.frames_out);
    console_puts(", not from the host ");
    console_uint(net.stats.not_host);
    console_puts(", queue full ");
    console_uint(net.stats.rx_queue_full);
    console_puts("\n");
}

int main(void)
{
    board_solenoids_off();
    console_init();
    console_puts("\nExoStudy device firmware " EXO_FIRMWARE_VERSION
                 ", mps2-an500 under QEMU (emulation only), protocol ");
    console_uint(EXO_WIRE_VERSION);
    console_puts("\n");
    timebase_init();

    emu_block blk;
    prov_error perr;
    emu_error err = emu_parse(_emu_block, EMU_BLOCK_SIZE, &blk, &perr);
    if (err == EMU_PROV) {
        halt(prov_error_name(perr));
    } else if (err != EMU_OK) {
        halt(emu_error_name(err));
    }
    entropy_init(blk.seed);
    /* The block is RAM here: leave no key or seed behind in it. */
    wipe((volatile uint8_t *)(uintptr_t)_emu_block, EMU_BLOCK_SIZE);
    wipe(blk.seed, sizeof blk.seed);

    exo_hmac_key kid;
    uint8_t digest[EXO_SHA256_BYTES];
    exo_hmac_set_key(&kid, blk.prov.key, sizeof blk.prov.key);
    exo_hmac_sha256(&kid, (const uint8_t *)"exostudy key id", 15u, 0, 0u, digest);
    wipe((volatile uint8_t *)&kid, sizeof kid);
    console_puts("device ");
    console_ipv4(blk.prov.device_ip);
    console_puts(" port ");
    console_uint(blk.prov.udp_port);
    console_puts(", host ");
    console_ipv4(blk.prov.host_ip);
    console_puts(", key id ");
    console_hex(digest, 8u);
    console_puts(", unique id ");
    console_hex(blk.unique_id, EMU_ID_BYTES);
    console_puts("\n");

    if (lan9118_init(blk.prov.mac) != 0) {
        halt("no LAN9118 answers at 0xA0000000");
    }
    net_config ncfg = {.ip = blk.prov.device_ip,
                       .netmask = blk.prov.netmask,
                       .udp_port = blk.prov.udp_port,
                       .peer_ip = blk.prov.host_ip};
    for (unsigned i = 0; i < NET_MAC_LEN; i++) {
        ncfg.mac[i] = blk.prov.mac[i];
    }
    net_stack_init(&net, &ncfg, lan9118_send, 0);

    exo_board board;
    board_fill(&board, &net);
    exo_config cfg = {0};
    for (unsigned i = 0; i < EXO_KEY_BYTES; i++) {
        cfg.key[i] = blk.prov.key[i];
    }
    cfg.host_ip = blk.prov.host_ip;
    cfg.sample_period_us = EXO_SAMPLE_PERIOD_US;
    cfg.bus = EXO_BUS_CHIP_SELECTS;
    cfg.rate_factor = 1;
    for (unsigned i = 0; i < EMU_ID_BYTES; i++) {
        cfg.unique_id[i] = blk.unique_id[i];
    }
    for (unsigned i = 0; i < sizeof FIRMWARE_NAME - 1u; i++) {
        cfg.firmware[i] = FIRMWARE_NAME[i];
    }
    int rc = exo_device_init(&dev, &board, &cfg);
    wipe(cfg.key, sizeof cfg.key);
    wipe(blk.prov.key, sizeof blk.prov.key);
    if (rc != 0) {
        halt("the device core refused to start");
    }
    wakeups_init();
    console_puts("running: waiting for the host\n");

    uint64_t now = timebase_now_us();
    uint64_t due = now;
    uint64_t next_report = now + REPORT_US;
    for (;;) {
        now = timebase_now_us();
        size_t n;
        for (unsigned i = 0; i < RX_FRAMES_PER_PASS && (LAN_RX_FIFO_INF >> 16 & 0xFFu) != 0u;
             i++) {
            n = lan9118_receive(frame, sizeof frame);
            if (n > 0u) {
                net_stack_input(&net, frame, n, now);
            }
        }
        if (net.rx_count > 0u || now >= due) {
            uint32_t wait = exo_device_poll(&dev);
            due = timebase_now_us() + wait;
        }
        if (now >= next_report) {
            print_report();
            next_report = now + REPORT_US;
        }
        if (net.rx_count == 0u && (LAN_RX_FIFO_INF >> 16 & 0xFFu) == 0u &&
            timebase_now_us() < due) {
            __asm__ volatile("wfi");
        }
    }
}
