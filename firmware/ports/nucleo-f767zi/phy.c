/* phy.c - MDIO access through the MAC's MII address/data registers. */
#include "phy.h"

#include "clock.h"
#include "pins.h"

#define REG_BCR 0u
#define REG_BSR 1u
#define REG_ID1 2u
#define REG_PSCSR 31u             /* LAN8742A special control/status */
#define BCR_RESET (1u << 15)
#define BCR_AUTONEG (1u << 12)
#define BCR_RESTART_AN (1u << 9)
#define BSR_LINK (1u << 2)
#define BSR_AN_DONE (1u << 5)
#define PSCSR_AUTODONE (1u << 12)
#define LAN8742A_ID1 0x0007u      /* OUI bits of Microchip/SMSC */
#define MDC_RANGE_60_100MHZ 0u    /* CR = 000: MDC = HCLK / 42, 2.3 MHz at 96 MHz */
#define MDIO_TIMEOUT_CYCLES (CLOCK_HCLK_HZ / 1000u) /* 1 ms; a transaction takes ~30 us */

static int mdio_wait(void)
{
    uint32_t start = DWT_CYCCNT;
    while (ETH_MACMIIAR & ETH_MACMIIAR_MB) {
        if (DWT_CYCCNT - start > MDIO_TIMEOUT_CYCLES) {
            return -1;
        }
    }
    return 0;
}

static uint32_t miiar(uint32_t reg)
{
    return (PHY_ADDRESS << ETH_MACMIIAR_PA_SHIFT) | (reg << ETH_MACMIIAR_MR_SHIFT) |
           (MDC_RANGE_60_100MHZ << ETH_MACMIIAR_CR_SHIFT) | ETH_MACMIIAR_MB;
}

static int mdio_read(uint32_t reg, uint16_t *value)
{
    if (mdio_wait() != 0) {
        return -1;
    }
    ETH_MACMIIAR = miiar(reg);
    if (mdio_wait() != 0) {
        return -1;
    }
    *value = (uint16_t)ETH_MACMIIDR;
    return 0;
}

static int mdio_write(uint32_t reg, uint16_t value)
{
    if (mdio_wait() != 0) {
        return -1;
    }
    ETH_MACMIIDR = value;
    ETH_MACMIIAR = miiar(reg) | ETH_MACMIIAR_MW;
    return mdio_wait();
}

int phy_init(void)
{
    uint16_t v;
    if (mdio_read(REG_ID1, &v) != 0 || v != LAN8742A_ID1) {
        return -1;
    }
    if (mdio_write(REG_BCR, BCR_RESET) != 0) {
        return -1;
    }
    /* The reset bit clears itself within 0.5 s (datasheet); allow a second. */
    for (int i = 0; i < 1000; i++) {
        clock_delay_cycles(CLOCK_HCLK_HZ / 1000u);
        if (mdio_read(REG_BCR, &v) != 0) {
            return -1;
        }
        if ((v & BCR_RESET) == 0u) {
            return mdio_write(REG_BCR, BCR_AUTONEG | BCR_RESTART_AN);
        }
    }
    return -1;
}

int phy_poll(phy_link *out)
{
    uint16_t bsr, pscsr;
    /* The link bit latches low: the first read reports a drop since the last read. */
    if (mdio_read(REG_BSR, &bsr) != 0 || mdio_read(REG_BSR, &bsr) != 0) {
        return -1;
    }
    out->up = (bsr & BSR_LINK) != 0u && (bsr & BSR_AN_DONE) != 0u;
    out->full = 0;
    out->fast = 0;
    if (!out->up) {
        return 0;
    }
    if (mdio_read(REG_PSCSR, &pscsr) != 0) {
        return -1;
    }
    /* Bits 4:2 speed indication: 001 10 half, 101 10 full, 010 100 half, 110 100 full. */
    uint32_t speed = (pscsr >> 2) & 7u;
    out->fast = (speed & 2u) != 0u;
    out->full = (speed & 4u) != 0u;
    return 0;
}
