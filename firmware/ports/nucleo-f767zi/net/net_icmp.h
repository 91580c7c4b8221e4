/*
 * net_icmp.h - ICMP echo (RFC 792), so that `ping` works during bring-up.
 *
 * Ping is the first check that the cable, the PHY, the MAC driver, ARP and the
 * addresses are right, before any key or protocol is involved.
 */
#ifndef NET_ICMP_H
#define NET_ICMP_H

#include <stddef.h>
#include <stdint.h>

/* If `in` (`len` bytes, an IPv4 payload) is a well-formed echo request, write the echo
 * reply to `out` (same length) and return `len`; otherwise return 0. */
size_t net_icmp_echo_reply(uint8_t *out, const uint8_t *in, size_t len);

#endif /* NET_ICMP_H */
