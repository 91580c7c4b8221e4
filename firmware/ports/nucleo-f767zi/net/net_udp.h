/*
 * net_udp.h - UDP (RFC 768) over IPv4 with the pseudo-header checksum.
 */
#ifndef NET_UDP_H
#define NET_UDP_H

#include <stddef.h>
#include <stdint.h>

#define NET_UDP_HDR 8

typedef enum {
    NET_UDP_OK = 0,
    NET_UDP_SHORT,    /* fewer bytes than a header */
    NET_UDP_LENGTH,   /* length field below 8 or beyond the IP payload */
    NET_UDP_CHECKSUM  /* checksum present and wrong */
} net_udp_error;

typedef struct {
    uint16_t src_port;
    uint16_t dst_port;
    const uint8_t *payload; /* points into the parsed buffer */
    size_t len;
} net_udp;

/* Check and split the UDP datagram at `p` (`len` = IPv4 payload length). A zero
 * checksum means "none sent" (allowed over IPv4) and is accepted. */
net_udp_error net_udp_parse(const uint8_t *p, size_t len, uint32_t src_ip, uint32_t dst_ip,
                            net_udp *out);

/* Write header and payload at `p` with the checksum filled in; returns 8 + len. */
size_t net_udp_build(uint8_t *p, uint32_t src_ip, uint32_t dst_ip, uint16_t src_port,
                     uint16_t dst_port, const uint8_t *payload, size_t len);

#endif /* NET_UDP_H */
