/*
 * net_eth.h - Ethernet II framing: the 14-byte header and the size limits.
 *
 * The MAC hardware adds the preamble and the frame check sequence on send and checks
 * (and, on this board, leaves) the FCS on receive; frames here start at the
 * destination address and end at the payload.
 */
#ifndef NET_ETH_H
#define NET_ETH_H

#include <stdint.h>

#include "net_bytes.h"

#define NET_MAC_LEN 6
#define NET_ETH_HDR 14
#define NET_ETH_MIN 60           /* shortest frame without FCS; shorter ones are padded */
#define NET_ETH_MTU 1500         /* largest payload */
#define NET_ETH_MAX (NET_ETH_HDR + NET_ETH_MTU)
#define NET_ETHERTYPE_IPV4 0x0800u
#define NET_ETHERTYPE_ARP 0x0806u

static inline void net_eth_header(uint8_t *frame, const uint8_t dst[NET_MAC_LEN],
                                  const uint8_t src[NET_MAC_LEN], uint16_t type)
{
    net_copy(frame, dst, NET_MAC_LEN);
    net_copy(frame + NET_MAC_LEN, src, NET_MAC_LEN);
    net_put16(frame + 2 * NET_MAC_LEN, type);
}

#endif /* NET_ETH_H */
