/* net_udp.c - UDP datagram checks and construction. */
#include "net_udp.h"

#include "net_bytes.h"
#include "net_checksum.h"
#include "net_ipv4.h"

/* Sum of the IPv4 pseudo-header: addresses, protocol, UDP length. */
static uint32_t pseudo_sum(uint32_t src_ip, uint32_t dst_ip, size_t udp_len)
{
    uint8_t ph[12];
    net_put32(ph, src_ip);
    net_put32(ph + 4, dst_ip);
    ph[8] = 0u;
    ph[9] = NET_IPPROTO_UDP;
    net_put16(ph + 10, (uint16_t)udp_len);
    return net_sum(0, ph, sizeof ph);
}

net_udp_error net_udp_parse(const uint8_t *p, size_t len, uint32_t src_ip, uint32_t dst_ip,
                            net_udp *out)
{
    if (len < NET_UDP_HDR) {
        return NET_UDP_SHORT;
    }
    size_t ulen = net_get16(p + 4);
    if (ulen < NET_UDP_HDR || ulen > len) {
        return NET_UDP_LENGTH;
    }
    if (net_get16(p + 6) != 0u) {
        if (net_fold(net_sum(pseudo_sum(src_ip, dst_ip, ulen), p, ulen)) != 0u) {
            return NET_UDP_CHECKSUM;
        }
    }
    out->src_port = net_get16(p);
    out->dst_port = net_get16(p + 2);
    out->payload = p + NET_UDP_HDR;
    out->len = ulen - NET_UDP_HDR;
    return NET_UDP_OK;
}

size_t net_udp_build(uint8_t *p, uint32_t src_ip, uint32_t dst_ip, uint16_t src_port,
                     uint16_t dst_port, const uint8_t *payload, size_t len)
{
    size_t ulen = NET_UDP_HDR + len;
    net_put16(p, src_port);
    net_put16(p + 2, dst_port);
    net_put16(p + 4, (uint16_t)ulen);
    net_put16(p + 6, 0u);
    net_copy(p + NET_UDP_HDR, payload, (unsigned)len);
    uint16_t sum = net_fold(net_sum(pseudo_sum(src_ip, dst_ip, ulen), p, ulen));
    /* A computed 0 is sent as 0xFFFF: 0 on the wire means "no checksum". */
    net_put16(p + 6, sum == 0u ? 0xFFFFu : sum);
    return ulen;
}
