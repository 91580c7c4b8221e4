/*
 * net_ipv4.h - the IPv4 header (RFC 791): checks on receive, a fixed header on send.
 *
 * The device never fragments and never reassembles: every protocol packet fits one
 * datagram (largest 165 bytes), so a fragment can only be foreign traffic and is
 * dropped.
 */
#ifndef NET_IPV4_H
#define NET_IPV4_H

#include <stddef.h>
#include <stdint.h>

#define NET_IPV4_HDR 20
#define NET_IPPROTO_ICMP 1u
#define NET_IPPROTO_UDP 17u
#define NET_IPV4_TTL 64u

typedef enum {
    NET_IPV4_OK = 0,
    NET_IPV4_SHORT,         /* fewer bytes than a header */
    NET_IPV4_VERSION,       /* not version 4 */
    NET_IPV4_HEADER_LENGTH, /* IHL below 5 or beyond the data */
    NET_IPV4_TOTAL_LENGTH,  /* total length below the header or beyond the frame */
    NET_IPV4_CHECKSUM,      /* header checksum wrong */
    NET_IPV4_FRAGMENT       /* more-fragments set or a non-zero fragment offset */
} net_ipv4_error;

typedef struct {
    uint32_t src;           /* host byte order */
    uint32_t dst;
    uint8_t proto;
    const uint8_t *payload; /* points into the parsed buffer */
    size_t payload_len;     /* from the total length: Ethernet padding excluded */
} net_ipv4;

/* Check and split the IPv4 packet at `p` (`len` bytes, may include padding). */
net_ipv4_error net_ipv4_parse(const uint8_t *p, size_t len, net_ipv4 *out);

/* Write a 20-byte header (no options, don't-fragment set, TTL 64) with its checksum,
 * for a payload of `payload_len` bytes. Returns NET_IPV4_HDR. */
size_t net_ipv4_header(uint8_t *p, uint32_t src, uint32_t dst, uint8_t proto, uint16_t id,
                       size_t payload_len);

#endif /* NET_IPV4_H */
