/*
 * net_stack.h - the device's whole network stack: static IPv4, ARP, ICMP echo and UDP
 * on one port, over any function that can send an Ethernet frame.
 *
 * It knows one peer, the host: it learns the host's MAC address from the host's ARP
 * packets and IPv4 frames (and asks for it with an ARP request when it has to send
 * first). It keeps received UDP datagrams in a small queue until the device core takes
 * them. No routing: the host must be on the same Ethernet segment (the protocol runs on
 * a dedicated network). Nothing here touches hardware, so it is tested on a desktop.
 *
 * Floods: a UDP datagram or a ping whose source address is not the host's is dropped
 * before its checksum is computed, before it could take a place in the queue and
 * without an answer (counted in `not_host`), so a flood from any other machine on the
 * segment can neither crowd the host's commands out of the queue, nor make the device
 * transmit, nor cost the device core any work. A full queue drops the newcomer, never
 * a queued datagram. (Datagrams that spoof the host's address do reach the queue; the
 * core caps how many of those it authenticates per sample period.)
 *
 * Trusting the source MAC of the host's frames lets another machine on the segment
 * divert the samples (a denial of service, which the host sees as a link outage), but
 * not forge or replay anything: every protocol packet carries an HMAC tag.
 */
#ifndef NET_STACK_H
#define NET_STACK_H

#include <stddef.h>
#include <stdint.h>

#include "net_eth.h"
#include "net_udp.h"
#include "net_ipv4.h"

#define NET_RXQ_LEN 4 /* datagrams waiting for the core; at 100 Hz it takes them within 10 ms */
#define NET_UDP_MAX (NET_ETH_MTU - NET_IPV4_HDR - NET_UDP_HDR) /* 1472 */
#define NET_ARP_RETRY_US 100000u /* at most one ARP request for the host per 100 ms */

typedef struct {
    uint8_t mac[NET_MAC_LEN]; /* the device's own address */
    uint32_t ip;              /* the device's IPv4 address, host byte order */
    uint32_t netmask;
    uint16_t udp_port;        /* the one port datagrams are accepted on */
    uint32_t peer_ip;         /* the host, whose MAC address is learned */
} net_config;

/* Counters, all saturating-free u32 (they wrap after 4e9 events: years at 100 Hz). */
typedef struct {
    uint32_t frames_in;
    uint32_t frames_out;
    uint32_t tx_errors;          /* the link function refused a frame */
    uint32_t not_for_us;         /* unicast to another MAC, unknown EtherType, other IP */
    uint32_t arp_replies_sent;
    uint32_t arp_requests_sent;
    uint32_t ipv4_errors;        /* failed net_ipv4_parse */
    uint32_t udp_errors;         /* failed net_udp_parse */
    uint32_t udp_wrong_port;
    uint32_t not_host;           /* UDP datagram or ping from another source: dropped */
    uint32_t icmp_echo_replies;
    uint32_t rx_queue_full;      /* datagram dropped: the core was not taking them */
    uint32_t tx_no_peer_mac;     /* datagram not sent: the host's MAC is not known yet */
    uint32_t peer_mac_changes;   /* the host's MAC was learned or changed */
} net_stats;

typedef int (*net_link_send)(void *ctx, const uint8_t *frame, size_t len);

typedef struct {
    uint32_t src_ip;
    uint16_t src_port;
    uint16_t len;
    uint8_t data[NET_UDP_MAX];
} net_datagram;

typedef struct {
    net_config cfg;
    net_link_send link_send;
    void *link_ctx;
    uint8_t peer_mac[NET_MAC_LEN];
    int peer_mac_known;
    int arp_sent_once;
    uint64_t last_arp_us;
    uint16_t ip_id;
    net_datagram rxq[NET_RXQ_LEN];
    unsigned rx_head;
    unsigned rx_count;
    uint8_t tx[NET_ETH_MAX];
    net_stats stats;
} net_stack;

void net_stack_init(net_stack *s, const net_config *cfg, net_link_send send, void *ctx);

/* Handle one received Ethernet frame (destination address first, FCS removed). */
void net_stack_input(net_stack *s, const uint8_t *frame, size_t len, uint64_t now_us);

/* Send `len` bytes to (dst_ip, dst_port) from the configured port. Returns 0, or -1 if
 * the host's MAC is not known yet (an ARP request goes out, at most once per
 * NET_ARP_RETRY_US), the payload is too long, or the link refused the frame. */
int net_stack_send_udp(net_stack *s, uint32_t dst_ip, uint16_t dst_port, const uint8_t *payload,
                       size_t len, uint64_t now_us);

/* Take the oldest queued datagram: its length (copied only if it fits `cap`; a longer
 * one is consumed and its true length returned), or 0 if none is queued. */
long net_stack_receive(net_stack *s, uint8_t *buf, size_t cap, uint32_t *src_ip,
                       uint16_t *src_port);

#endif /* NET_STACK_H */
