/*
 * eth_mac.h - the STM32F7 Ethernet MAC and its DMA, in RMII mode, polled (no
 * interrupts): ring of 4 receive and 2 transmit buffers in SRAM2, normal (4-word)
 * descriptors in chained mode.
 *
 * The data cache stays off (clock.c), so the CPU and the DMA see the same memory
 * without cache maintenance. No checksum offload: the network stack computes every
 * checksum itself, which keeps it testable off the board.
 */
#ifndef ETH_MAC_H
#define ETH_MAC_H

#include <stddef.h>
#include <stdint.h>

#define ETH_RX_BUFS 4u
#define ETH_TX_BUFS 2u

typedef struct {
    uint32_t rx_frames;
    uint32_t rx_errors;   /* descriptor error summary, or a frame split over buffers */
    uint32_t tx_frames;
    uint32_t tx_busy;     /* no free transmit descriptor in time */
    uint32_t link_changes;
} eth_stats;

/* Pins, clocks, MAC address, PHY, descriptors, start. 0, or -1 if the DMA reset never
 * completes (no 50 MHz reference clock from the PHY) or no PHY answers. */
int eth_init(const uint8_t mac[6]);

/* The link function for net_stack: copy the frame into a free descriptor and start
 * it. 0, or -1 if no descriptor freed up within 1 ms or the frame is too long. */
int eth_send(void *ctx, const uint8_t *frame, size_t len);

/* The next received frame, FCS removed: its length and *frame pointing into the DMA
 * buffer (valid until eth_rx_release), or 0 if none. Frames with errors are skipped. */
size_t eth_rx_take(const uint8_t **frame);
void eth_rx_release(void);

/* Check the PHY (call every ~250 ms) and match the MAC to the negotiated speed and
 * duplex. Returns 1 if the link is up. */
int eth_link_poll(void);

const eth_stats *eth_get_stats(void);

#endif /* ETH_MAC_H */
