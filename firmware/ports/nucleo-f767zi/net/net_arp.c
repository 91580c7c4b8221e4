/* net_arp.c - ARP packet parsing and building (RFC 826). */
#include "net_arp.h"

int net_arp_parse(const uint8_t *p, size_t len, net_arp *out)
{
    if (len < NET_ARP_LEN) {
        return -1;
    }
    /* Hardware type 1 (Ethernet), protocol IPv4, 6-byte and 4-byte addresses. */
    if (net_get16(p) != 1u || net_get16(p + 2) != NET_ETHERTYPE_IPV4 || p[4] != NET_MAC_LEN ||
        p[5] != 4u) {
        return -1;
    }
    out->oper = net_get16(p + 6);
    if (out->oper != NET_ARP_REQUEST && out->oper != NET_ARP_REPLY) {
        return -1;
    }
    net_copy(out->sha, p + 8, NET_MAC_LEN);
    out->spa = net_get32(p + 14);
    net_copy(out->tha, p + 18, NET_MAC_LEN);
    out->tpa = net_get32(p + 24);
    return 0;
}

size_t net_arp_build(uint8_t *p, const net_arp *a)
{
    net_put16(p, 1u);
    net_put16(p + 2, NET_ETHERTYPE_IPV4);
    p[4] = NET_MAC_LEN;
    p[5] = 4u;
    net_put16(p + 6, a->oper);
    net_copy(p + 8, a->sha, NET_MAC_LEN);
    net_put32(p + 14, a->spa);
    net_copy(p + 18, a->tha, NET_MAC_LEN);
    net_put32(p + 24, a->tpa);
    return NET_ARP_LEN;
}
