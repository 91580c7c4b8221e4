/*
 * lan9118.c - the LAN9118's system registers, MAC registers (reached through the
 * MAC_CSR command/data pair) and FIFOs, as the SMSC LAN9118 datasheet describes them.
 *
 * Byte order: the FIFOs carry frame bytes little-endian within each 32-bit word (the
 * first byte of the frame is the word's lowest byte), which is the Cortex-M's own
 * order, so a word is split into bytes with shifts and no swapping.
 */
#include "lan9118.h"

#include "mps2_regs.h"

#define LAN(off) REG32(LAN9118_BASE + (off))
#define RX_DATA_FIFO LAN(0x00u)
#define TX_DATA_FIFO LAN(0x20u)
#define RX_STATUS_FIFO LAN(0x40u)
#define ID_REV LAN(0x50u)
#define INT_EN LAN(0x5Cu)
#define BYTE_TEST LAN(0x64u)
#define RX_CFG LAN(0x6Cu)
#define TX_CFG LAN(0x70u)
#define HW_CFG LAN(0x74u)
#define RX_FIFO_INF LAN(0x7Cu)
#define TX_FIFO_INF LAN(0x80u)
#define PMT_CTRL LAN(0x84u)
#define MAC_CSR_CMD LAN(0xA4u)
#define MAC_CSR_DATA LAN(0xA8u)

#define BYTE_TEST_VALUE 0x87654321u
#define HW_CFG_SRST (1u << 0)
#define PMT_CTRL_READY (1u << 0)
#define TX_CFG_TX_ON (1u << 1)
#define TX_CFG_TXSAO (1u << 2) /* status FIFO may overrun: nobody reads it */
#define MAC_CSR_BUSY (1u << 31)
#define MAC_CSR_READ (1u << 30)

/* MAC registers (indirect). */
#define MAC_CR 1u
#define MAC_ADDRH 2u
#define MAC_ADDRL 3u
#define MAC_CR_RXEN (1u << 2)
#define MAC_CR_TXEN (1u << 3)

/* RX status word. */
#define RXS_LENGTH(s) (((s) >> 16) & 0x3FFFu) /* frame length including the 4-byte FCS */
#define RXS_ERROR (1u << 15)
#define RXS_USED(inf) (((inf) >> 16) & 0xFFu) /* RX_FIFO_INF: status words waiting */

/* TX command A and B. */
#define TXA_FIRST_SEG (1u << 13)
#define TXA_LAST_SEG (1u << 12)
#define TX_FREE_BYTES(inf) ((inf) & 0xFFFFu)

#define SPIN_LIMIT 100000u /* register polls before a step counts as failed */

lan9118_stats lan9118_counters;

static int mac_wait(void)
{
    for (uint32_t i = 0; i < SPIN_LIMIT; i++) {
        if ((MAC_CSR_CMD & MAC_CSR_BUSY) == 0u) {
            return 0;
        }
    }
    return -1;
}

static int mac_write(uint32_t reg, uint32_t value)
{
    if (mac_wait() != 0) {
        return -1;
    }
    MAC_CSR_DATA = value;
    MAC_CSR_CMD = MAC_CSR_BUSY | reg;
    return mac_wait();
}

int lan9118_init(const uint8_t mac[6])
{
    if (BYTE_TEST != BYTE_TEST_VALUE) {
        return -1; /* nothing there, or a bus in the wrong byte order */
    }
    HW_CFG = HW_CFG_SRST;
    uint32_t i = 0;
    while ((HW_CFG & HW_CFG_SRST) != 0u || (PMT_CTRL & PMT_CTRL_READY) == 0u) {
        if (++i == SPIN_LIMIT) {
            return -1;
        }
    }
    (void)ID_REV;
    INT_EN = 0u;   /* polled */
    RX_CFG = 0u;   /* no offset, no end padding */
    uint32_t lo = (uint32_t)mac[0] | (uint32_t)mac[1] << 8 | (uint32_t)mac[2] << 16 |
                  (uint32_t)mac[3] << 24;
    uint32_t hi = (uint32_t)mac[4] | (uint32_t)mac[5] << 8;
    if (mac_write(MAC_ADDRL, lo) != 0 || mac_write(MAC_ADDRH, hi) != 0) {
        return -1;
    }
    TX_CFG = TX_CFG_TX_ON | TX_CFG_TXSAO;
    /* Exact address match plus broadcast (for ARP): promiscuous and pass-all off. */
    return mac_write(MAC_CR, MAC_CR_TXEN | MAC_CR_RXEN);
}

size_t lan9118_receive(uint8_t *buf, size_t cap)
{
    if (RXS_USED(RX_FIFO_INF) == 0u) {
        return 0u;
    }
    uint32_t status = RX_STATUS_FIFO;
    uint32_t len = RXS_LENGTH(status);
    uint32_t words = (len + 3u) / 4u;
    int keep = (status & RXS_ERROR) == 0u && len >= 4u && len - 4u <= cap;
    if (!keep) {
        /* Read the frame out word by word: simple, and the same on every LAN9118
         * model whatever its fast-forward support. */
        for (uint32_t w = 0; w < words; w++) {
            (void)RX_DATA_FIFO;
        }
        if ((status & RXS_ERROR) != 0u) {
            lan9118_counters.rx_errors++;
        } else {
            lan9118_counters.rx_too_long++;
        }
        return 0u;
    }
    size_t n = len - 4u; /* without the FCS */
    for (uint32_t w = 0; w < words; w++) {
        uint32_t v = RX_DATA_FIFO;
        for (uint32_t b = 0; b < 4u; b++) {
            size_t at = (size_t)w * 4u + b;
            if (at < n) {
                buf[at] = (uint8_t)(v >> (8u * b));
            }
        }
    }
    lan9118_counters.rx_frames++;
    return n;
}

int lan9118_send(void *ctx, const uint8_t *frame, size_t len)
{
    (void)ctx;
    if (len == 0u || len > LAN9118_FRAME_MAX - 4u) {
        return -1;
    }
    uint32_t words = (uint32_t)((len + 3u) / 4u);
    if (TX_FREE_BYTES(TX_FIFO_INF) < words * 4u + 8u) {
        lan9118_counters.tx_no_room++;
        return -1;
    }
    uint32_t n = (uint32_t)len;
    TX_DATA_FIFO = TXA_FIRST_SEG | TXA_LAST_SEG | n; /* one buffer, no offset */
    TX_DATA_FIFO = (lan9118_counters.tx_frames & 0xFFFFu) << 16 | n; /* tag, length */
    for (uint32_t w = 0; w < words; w++) {
        uint32_t v = 0u;
        for (uint32_t b = 0; b < 4u; b++) {
            uint32_t at = w * 4u + b;
            if (at < n) {
                v |= (uint32_t)frame[at] << (8u * b);
            }
        }
        TX_DATA_FIFO = v;
    }
    lan9118_counters.tx_frames++;
    return 0;
}
