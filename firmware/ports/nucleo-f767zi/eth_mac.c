/* eth_mac.c - Ethernet MAC/DMA registers and descriptors (RM0410 "Ethernet"). */
#include "eth_mac.h"

#include "clock.h"
#include "gpio.h"
#include "phy.h"

#define RX_BUFS ETH_RX_BUFS
#define TX_BUFS ETH_TX_BUFS
#define BUF_SIZE 1536u /* a full 1518-byte frame, rounded to a multiple of 32 */
#define TX_TIMEOUT_CYCLES (CLOCK_HCLK_HZ / 1000u)
#define RESET_TIMEOUT_CYCLES (CLOCK_HCLK_HZ / 10u)

/* Descriptor bits (normal descriptors). */
#define DES0_OWN (1u << 31)
#define TDES0_IC (1u << 30)
#define TDES0_LS (1u << 29)
#define TDES0_FS (1u << 28)
#define TDES0_TCH (1u << 20)
#define RDES0_FL_SHIFT 16u
#define RDES0_FL_MASK 0x3FFFu
#define RDES0_ES (1u << 15)
#define RDES0_FS (1u << 9)
#define RDES0_LS (1u << 8)
#define RDES1_RCH (1u << 14)

typedef struct {
    volatile uint32_t des0;
    volatile uint32_t des1;
    volatile uint32_t buf;
    volatile uint32_t next;
} eth_desc;

/* SRAM2 (see the linker script): reachable by the Ethernet DMA, never cached. */
#define ETH_DMA_MEM __attribute__((section(".eth_dma"), aligned(32)))
static eth_desc rx_desc[RX_BUFS] ETH_DMA_MEM;
static eth_desc tx_desc[TX_BUFS] ETH_DMA_MEM;
static uint8_t rx_buf[RX_BUFS][BUF_SIZE] ETH_DMA_MEM;
static uint8_t tx_buf[TX_BUFS][BUF_SIZE] ETH_DMA_MEM;

static unsigned rx_next;
static unsigned tx_next;
static int rx_holding;
static phy_link link;
static eth_stats stats;

static const pin_t RMII_PINS[] = {
    {PORT_A, 1u},  /* REF_CLK */
    {PORT_A, 2u},  /* MDIO */
    {PORT_A, 7u},  /* CRS_DV */
    {PORT_B, 13u}, /* TXD1 */
    {PORT_C, 1u},  /* MDC */
    {PORT_C, 4u},  /* RXD0 */
    {PORT_C, 5u},  /* RXD1 */
    {PORT_G, 11u}, /* TX_EN */
    {PORT_G, 13u}, /* TXD0 */
};

static void descriptors_init(void)
{
    for (unsigned i = 0; i < RX_BUFS; i++) {
        rx_desc[i].buf = (uint32_t)(uintptr_t)rx_buf[i];
        rx_desc[i].next = (uint32_t)(uintptr_t)&rx_desc[(i + 1u) % RX_BUFS];
        rx_desc[i].des1 = RDES1_RCH | BUF_SIZE;
        rx_desc[i].des0 = DES0_OWN;
    }
    for (unsigned i = 0; i < TX_BUFS; i++) {
        tx_desc[i].buf = (uint32_t)(uintptr_t)tx_buf[i];
        tx_desc[i].next = (uint32_t)(uintptr_t)&tx_desc[(i + 1u) % TX_BUFS];
        tx_desc[i].des1 = 0u;
        tx_desc[i].des0 = TDES0_TCH;
    }
    rx_next = 0u;
    tx_next = 0u;
    rx_holding = 0;
    ETH_DMARDLAR = (uint32_t)(uintptr_t)rx_desc;
    ETH_DMATDLAR = (uint32_t)(uintptr_t)tx_desc;
}

static void set_speed(const phy_link *l)
{
    uint32_t cr = ETH_MACCR & ~(ETH_MACCR_FES | ETH_MACCR_DM);
    if (l->fast) {
        cr |= ETH_MACCR_FES;
    }
    if (l->full) {
        cr |= ETH_MACCR_DM;
    }
    ETH_MACCR = cr;
}

int eth_init(const uint8_t mac[6])
{
    /* RMII must be selected while the MAC is in reset, before its clocks run. */
    RCC_APB2ENR |= RCC_APB2ENR_SYSCFGEN;
    (void)RCC_APB2ENR;
    SYSCFG_PMC |= SYSCFG_PMC_MII_RMII_SEL;
    for (unsigned i = 0; i < sizeof RMII_PINS / sizeof RMII_PINS[0]; i++) {
        gpio_alternate(RMII_PINS[i], AF_ETH, 0);
    }
    RCC_AHB1ENR |= RCC_AHB1ENR_ETHMACEN | RCC_AHB1ENR_ETHMACTXEN | RCC_AHB1ENR_ETHMACRXEN;
    (void)RCC_AHB1ENR;
    RCC_AHB1RSTR |= RCC_AHB1RSTR_ETHMACRST;
    RCC_AHB1RSTR &= ~RCC_AHB1RSTR_ETHMACRST;

    /* The DMA reset completes only with the PHY's 50 MHz reference clock running. */
    ETH_DMABMR |= ETH_DMABMR_SR;
    uint32_t start = DWT_CYCCNT;
    while (ETH_DMABMR & ETH_DMABMR_SR) {
        if (DWT_CYCCNT - start > RESET_TIMEOUT_CYCLES) {
            return -1;
        }
    }

    if (phy_init() != 0) {
        return -1;
    }

    /* Until the PHY reports the negotiated mode: 100 Mbit/s full duplex, the mode
     * every switch and host adapter offers. eth_link_poll corrects it. */
    ETH_MACCR = ETH_MACCR_CSTF | ETH_MACCR_FES | ETH_MACCR_DM;
    ETH_MACFFR = 0u; /* own address and broadcast only */
    ETH_MACA0HR = (uint32_t)mac[5] << 8 | mac[4];
    ETH_MACA0LR = (uint32_t)mac[3] << 24 | (uint32_t)mac[2] << 16 | (uint32_t)mac[1] << 8 | mac[0];
    ETH_MMCRIMR = 0xFFFFFFFFu; /* no MMC counter interrupts (none are enabled anyway) */
    ETH_MMCTIMR = 0xFFFFFFFFu;

    ETH_DMABMR = ETH_DMABMR_AAB | ETH_DMABMR_USP | (32u << ETH_DMABMR_RDP_SHIFT) |
                 ETH_DMABMR_FB | (32u << ETH_DMABMR_PBL_SHIFT);
    ETH_DMAIER = 0u;
    descriptors_init();

    /* Order from the manual: transmitter, flush, DMA transmit, receiver, DMA receive. */
    ETH_DMAOMR = ETH_DMAOMR_RSF | ETH_DMAOMR_TSF;
    ETH_MACCR |= ETH_MACCR_TE;
    ETH_DMAOMR |= ETH_DMAOMR_FTF;
    start = DWT_CYCCNT;
    while (ETH_DMAOMR & ETH_DMAOMR_FTF) {
        if (DWT_CYCCNT - start > RESET_TIMEOUT_CYCLES) {
            return -1;
        }
    }
    ETH_DMAOMR |= ETH_DMAOMR_ST;
    ETH_MACCR |= ETH_MACCR_RE;
    ETH_DMAOMR |= ETH_DMAOMR_SR;
    link.up = 0;
    return 0;
}

int eth_send(void *ctx, const uint8_t *frame, size_t len)
{
    (void)ctx;
    if (len > BUF_SIZE) {
        return -1;
    }
    eth_desc *d = &tx_desc[tx_next];
    uint32_t start = DWT_CYCCNT;
    while (d->des0 & DES0_OWN) {
        if (DWT_CYCCNT - start > TX_TIMEOUT_CYCLES) {
            stats.tx_busy++;
            return -1;
        }
    }
    uint8_t *b = tx_buf[tx_next];
    for (size_t i = 0; i < len; i++) {
        b[i] = frame[i];
    }
    d->des1 = (uint32_t)len;
    __asm__ volatile("dmb" ::: "memory"); /* buffer and length before ownership */
    d->des0 = DES0_OWN | TDES0_FS | TDES0_LS | TDES0_TCH;
    __asm__ volatile("dsb" ::: "memory");
    ETH_DMATPDR = 0u; /* resume if the DMA suspended on an empty ring */
    tx_next = (tx_next + 1u) % TX_BUFS;
    stats.tx_frames++;
    return 0;
}

size_t eth_rx_take(const uint8_t **frame)
{
    while (!rx_holding) {
        eth_desc *d = &rx_desc[rx_next];
        uint32_t s = d->des0;
        if (s & DES0_OWN) {
            return 0u;
        }
        uint32_t fl = (s >> RDES0_FL_SHIFT) & RDES0_FL_MASK;
        /* Whether FL still counts the 4-byte FCS or not, the IP and ARP layers bound
         * their data by their own length fields, so trailing bytes are harmless. */
        if ((s & RDES0_ES) || !(s & RDES0_FS) || !(s & RDES0_LS) || fl < 14u || fl > BUF_SIZE) {
            stats.rx_errors++;
            d->des0 = DES0_OWN;
            rx_next = (rx_next + 1u) % RX_BUFS;
            ETH_DMARPDR = 0u;
            continue;
        }
        if (fl > 1514u) {
            fl = 1514u; /* a full-size frame with its FCS still attached */
        }
        rx_holding = 1;
        stats.rx_frames++;
        *frame = rx_buf[rx_next];
        return fl;
    }
    return 0u; /* the caller forgot eth_rx_release */
}

void eth_rx_release(void)
{
    if (!rx_holding) {
        return;
    }
    rx_desc[rx_next].des0 = DES0_OWN;
    __asm__ volatile("dsb" ::: "memory");
    ETH_DMARPDR = 0u; /* resume if the DMA stopped for want of a buffer */
    rx_next = (rx_next + 1u) % RX_BUFS;
    rx_holding = 0;
}

int eth_link_poll(void)
{
    phy_link now;
    if (phy_poll(&now) != 0) {
        return 0;
    }
    if (now.up != link.up || now.fast != link.fast || now.full != link.full) {
        stats.link_changes++;
        if (now.up) {
            set_speed(&now);
        }
        link = now;
    }
    return link.up;
}

const eth_stats *eth_get_stats(void)
{
    return &stats;
}
