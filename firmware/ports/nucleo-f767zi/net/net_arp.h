/*
 * net_arp.h - ARP (RFC 826) for IPv4 over Ethernet: the 28-byte packet.
 *
 * The device answers requests for its own address (so the host can reach it) and asks
 * for the host's address when it must send a sample before it has heard from the host.
 */
#ifndef NET_ARP_H
#define NET_ARP_H

#include <stddef.h>
#include <stdint.h>

#include "net_eth.h"

#define NET_ARP_LEN 28
#define NET_ARP_REQUEST 1u
#define NET_ARP_REPLY 2u

typedef struct {
    uint16_t oper;              /* NET_ARP_REQUEST or NET_ARP_REPLY */
    uint8_t sha[NET_MAC_LEN];   /* sender hardware address */
    uint32_t spa;               /* sender IPv4 address, host byte order */
    uint8_t tha[NET_MAC_LEN];   /* target hardware address (zero in a request) */
    uint32_t tpa;               /* target IPv4 address */
} net_arp;

/* 0 if `p` (the Ethernet payload, `len` bytes) is an Ethernet/IPv4 ARP request or
 * reply, filled into `out`; -1 otherwise. Trailing padding is allowed. */
int net_arp_parse(const uint8_t *p, size_t len, net_arp *out);

/* Write `a` as the 28-byte packet at `p`; returns NET_ARP_LEN. */
size_t net_arp_build(uint8_t *p, const net_arp *a);

#endif /* NET_ARP_H */
