/* net_stack.c - demultiplex frames, answer ARP and ping, queue and send UDP. */
#include "net_stack.h"

#include "net_arp.h"
#include "net_icmp.h"

static const uint8_t BROADCAST[NET_MAC_LEN] = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};

void net_stack_init(net_stack *s, const net_config *cfg, net_link_send send, void *ctx)
{
    uint8_t *raw = (uint8_t *)s;
    for (size_t i = 0; i < sizeof *s; i++) {
        raw[i] = 0u;
    }
    s->cfg = *cfg;
    s->link_send = send;
    s->link_ctx = ctx;
}

static int transmit(net_stack *s, size_t len)
{
    /* Pad to the Ethernet minimum so that no stale bytes go out as padding. */
    while (len < NET_ETH_MIN) {
        s->tx[len++] = 0u;
    }
    if (s->link_send(s->link_ctx, s->tx, len) != 0) {
        s->stats.tx_errors++;
        return -1;
    }
    s->stats.frames_out++;
    return 0;
}

static void learn_peer(net_stack *s, uint32_t ip, const uint8_t mac[NET_MAC_LEN])
{
    if (ip != s->cfg.peer_ip || (mac[0] & 1u) != 0u) {
        return; /* not the host, or a multicast source (invalid) */
    }
    if (!s->peer_mac_known || !net_equal(s->peer_mac, mac, NET_MAC_LEN)) {
        net_copy(s->peer_mac, mac, NET_MAC_LEN);
        s->peer_mac_known = 1;
        s->stats.peer_mac_changes++;
    }
}

static void send_arp(net_stack *s, uint16_t oper, const uint8_t dst_mac[NET_MAC_LEN],
                     const uint8_t tha[NET_MAC_LEN], uint32_t tpa)
{
    net_arp a;
    a.oper = oper;
    net_copy(a.sha, s->cfg.mac, NET_MAC_LEN);
    a.spa = s->cfg.ip;
    net_copy(a.tha, tha, NET_MAC_LEN);
    a.tpa = tpa;
    net_eth_header(s->tx, dst_mac, s->cfg.mac, NET_ETHERTYPE_ARP);
    size_t n = net_arp_build(s->tx + NET_ETH_HDR, &a);
    if (transmit(s, NET_ETH_HDR + n) == 0) {
        if (oper == NET_ARP_REPLY) {
            s->stats.arp_replies_sent++;
        } else {
            s->stats.arp_requests_sent++;
        }
    }
}

static void input_arp(net_stack *s, const uint8_t *p, size_t len)
{
    net_arp a;
    if (net_arp_parse(p, len, &a) != 0) {
        s->stats.not_for_us++;
        return;
    }
    learn_peer(s, a.spa, a.sha);
    if (a.oper == NET_ARP_REQUEST && a.tpa == s->cfg.ip) {
        send_arp(s, NET_ARP_REPLY, a.sha, a.sha, a.spa);
    }
}

static void input_udp(net_stack *s, const net_ipv4 *ip)
{
    net_udp u;
    if (net_udp_parse(ip->payload, ip->payload_len, ip->src, ip->dst, &u) != NET_UDP_OK) {
        s->stats.udp_errors++;
        return;
    }
    if (u.len == 0u) {
        s->stats.udp_errors++; /* empty: no protocol packet, and 0 means "none" to the core */
        return;
    }
    if (u.dst_port != s->cfg.udp_port) {
        s->stats.udp_wrong_port++;
        return;
    }
    if (s->rx_count == NET_RXQ_LEN) {
        s->stats.rx_queue_full++;
        return;
    }
    net_datagram *d = &s->rxq[(s->rx_head + s->rx_count) % NET_RXQ_LEN];
    d->src_ip = ip->src;
    d->src_port = u.src_port;
    d->len = (uint16_t)u.len; /* at most NET_UDP_MAX: it came in one frame */
    net_copy(d->data, u.payload, (unsigned)u.len);
    s->rx_count++;
}

static void input_icmp(net_stack *s, const uint8_t *frame, const net_ipv4 *ip)
{
    if (ip->payload_len > NET_ETH_MTU - NET_IPV4_HDR) {
        return;
    }
    uint8_t *out = s->tx + NET_ETH_HDR + NET_IPV4_HDR;
    size_t n = net_icmp_echo_reply(out, ip->payload, ip->payload_len);
    if (n == 0u) {
        return;
    }
    /* Answer the frame's sender directly: ping must work before the host's MAC is
     * known from an ARP exchange. Only the host gets here (input_ipv4). */
    net_eth_header(s->tx, frame + NET_MAC_LEN, s->cfg.mac, NET_ETHERTYPE_IPV4);
    net_ipv4_header(s->tx + NET_ETH_HDR, s->cfg.ip, ip->src, NET_IPPROTO_ICMP, s->ip_id++, n);
    if (transmit(s, NET_ETH_HDR + NET_IPV4_HDR + n) == 0) {
        s->stats.icmp_echo_replies++;
    }
}

static void input_ipv4(net_stack *s, const uint8_t *frame, size_t len)
{
    net_ipv4 ip;
    if (net_ipv4_parse(frame + NET_ETH_HDR, len - NET_ETH_HDR, &ip) != NET_IPV4_OK) {
        s->stats.ipv4_errors++;
        return;
    }
    if (ip.dst != s->cfg.ip) {
        s->stats.not_for_us++;
        return;
    }
    if (ip.src != s->cfg.peer_ip &&
        (ip.proto == NET_IPPROTO_UDP || ip.proto == NET_IPPROTO_ICMP)) {
        /* Only the host's datagrams are acted on: drop the rest before any checksum,
         * before they could occupy a place the host's commands need, and unanswered. */
        s->stats.not_host++;
        return;
    }
    learn_peer(s, ip.src, frame + NET_MAC_LEN);
    if (ip.proto == NET_IPPROTO_UDP) {
        input_udp(s, &ip);
    } else if (ip.proto == NET_IPPROTO_ICMP) {
        input_icmp(s, frame, &ip);
    } else {
        s->stats.not_for_us++;
    }
}

void net_stack_input(net_stack *s, const uint8_t *frame, size_t len, uint64_t now_us)
{
    (void)now_us;
    s->stats.frames_in++;
    if (len < NET_ETH_HDR || len > NET_ETH_MAX) {
        s->stats.not_for_us++;
        return;
    }
    if (!net_equal(frame, s->cfg.mac, NET_MAC_LEN) && !net_equal(frame, BROADCAST, NET_MAC_LEN)) {
        s->stats.not_for_us++;
        return;
    }
    uint16_t type = net_get16(frame + 2 * NET_MAC_LEN);
    if (type == NET_ETHERTYPE_ARP) {
        input_arp(s, frame + NET_ETH_HDR, len - NET_ETH_HDR);
    } else if (type == NET_ETHERTYPE_IPV4) {
        input_ipv4(s, frame, len);
    } else {
        s->stats.not_for_us++;
    }
}

int net_stack_send_udp(net_stack *s, uint32_t dst_ip, uint16_t dst_port, const uint8_t *payload,
                       size_t len, uint64_t now_us)
{
    if (len > NET_UDP_MAX) {
        s->stats.tx_errors++;
        return -1;
    }
    if (dst_ip != s->cfg.peer_ip || !s->peer_mac_known) {
        /* Only the host is ever a destination; ask for its address, rate-limited. */
        s->stats.tx_no_peer_mac++;
        if (dst_ip == s->cfg.peer_ip &&
            (!s->arp_sent_once || now_us - s->last_arp_us >= NET_ARP_RETRY_US)) {
            static const uint8_t zero[NET_MAC_LEN] = {0};
            s->arp_sent_once = 1;
            s->last_arp_us = now_us;
            send_arp(s, NET_ARP_REQUEST, BROADCAST, zero, dst_ip);
        }
        return -1;
    }
    uint8_t *udp = s->tx + NET_ETH_HDR + NET_IPV4_HDR;
    size_t n = net_udp_build(udp, s->cfg.ip, dst_ip, s->cfg.udp_port, dst_port, payload, len);
    net_ipv4_header(s->tx + NET_ETH_HDR, s->cfg.ip, dst_ip, NET_IPPROTO_UDP, s->ip_id++, n);
    net_eth_header(s->tx, s->peer_mac, s->cfg.mac, NET_ETHERTYPE_IPV4);
    return transmit(s, NET_ETH_HDR + NET_IPV4_HDR + n);
}

long net_stack_receive(net_stack *s, uint8_t *buf, size_t cap, uint32_t *src_ip,
                       uint16_t *src_port)
{
    if (s->rx_count == 0u) {
        return 0;
    }
    net_datagram *d = &s->rxq[s->rx_head];
    s->rx_head = (s->rx_head + 1u) % NET_RXQ_LEN;
    s->rx_count--;
    *src_ip = d->src_ip;
    *src_port = d->src_port;
    if (d->len <= cap) {
        net_copy(buf, d->data, d->len);
    }
    return (long)d->len;
}
