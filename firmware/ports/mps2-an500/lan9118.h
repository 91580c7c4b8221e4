/*
 * lan9118.h - a polled driver for the SMSC LAN9118 Ethernet controller (on QEMU's
 * mps2-an500 machine; the real MPS2 board carries the register-compatible LAN9220).
 *
 * The controller keeps received frames in its own FIFOs: a status word per frame and
 * the data, read out word by word. Sending is the reverse: two command words, then the
 * frame. No interrupts and no DMA: the main loop asks for one frame at a time.
 */
#ifndef LAN9118_H
#define LAN9118_H

#include <stddef.h>
#include <stdint.h>

#define LAN9118_FRAME_MAX 1518u /* largest frame with its FCS */

/* Reset the controller, set `mac` as its address, enable the transmitter and the
 * receiver (own address and broadcast only). Returns 0, or -1 if no LAN9118 answers
 * (byte-order test register wrong, or the reset never completes). */
int lan9118_init(const uint8_t mac[6]);

/* Copy the next received frame (destination address first, FCS removed) into `buf`
 * and return its length; 0 if none is waiting. A frame received with an error, or
 * longer than `cap`, is read out of the FIFO and dropped (counted), and 0 returned
 * for it; the next call looks at the following one. */
size_t lan9118_receive(uint8_t *buf, size_t cap);

/* Queue one frame (without FCS) for sending. Returns 0, or -1 if it is too long or
 * the transmit FIFO has no room (the frame is dropped, never retried). The link_send
 * signature of the network stack. */
int lan9118_send(void *ctx, const uint8_t *frame, size_t len);

typedef struct {
    uint32_t rx_frames;
    uint32_t rx_errors;    /* error summary bit set in the frame's status */
    uint32_t rx_too_long;  /* longer than the caller's buffer */
    uint32_t tx_frames;
    uint32_t tx_no_room;
} lan9118_stats;

extern lan9118_stats lan9118_counters;

#endif /* LAN9118_H */
