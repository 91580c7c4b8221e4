/* net_ipv4.c - IPv4 header checks and construction. */
#include "net_ipv4.h"

#include "net_bytes.h"
#include "net_checksum.h"

net_ipv4_error net_ipv4_parse(const uint8_t *p, size_t len, net_ipv4 *out)
{
    if (len < NET_IPV4_HDR) {
        return NET_IPV4_SHORT;
    }
    if ((p[0] >> 4) != 4u) {
        return NET_IPV4_VERSION;
    }
    size_t ihl = (size_t)(p[0] & 0x0Fu) * 4u;
    if (ihl < NET_IPV4_HDR || ihl > len) {
        return NET_IPV4_HEADER_LENGTH;
    }
    size_t total = net_get16(p + 2);
    if (total < ihl || total > len) {
        return NET_IPV4_TOTAL_LENGTH;
    }
    if (net_checksum(p, ihl) != 0u) {
        return NET_IPV4_CHECKSUM;
    }
    uint16_t frag = net_get16(p + 6);
    if ((frag & 0x2000u) != 0u || (frag & 0x1FFFu) != 0u) {
        return NET_IPV4_FRAGMENT;
    }
    out->proto = p[9];
    out->src = net_get32(p + 12);
    out->dst = net_get32(p + 16);
    out->payload = p + ihl;
    out->payload_len = total - ihl;
    return NET_IPV4_OK;
}

size_t net_ipv4_header(uint8_t *p, uint32_t src, uint32_t dst, uint8_t proto, uint16_t id,
                       size_t payload_len)
{
    p[0] = 0x45u; /* version 4, 5 words */
    p[1] = 0u;    /* DSCP/ECN */
    net_put16(p + 2, (uint16_t)(NET_IPV4_HDR + payload_len));
    net_put16(p + 4, id);
    net_put16(p + 6, 0x4000u); /* don't fragment */
    p[8] = NET_IPV4_TTL;
    p[9] = proto;
    net_put16(p + 10, 0u);
    net_put32(p + 12, src);
    net_put32(p + 16, dst);
    net_put16(p + 10, net_checksum(p, NET_IPV4_HDR));
    return NET_IPV4_HDR;
}
