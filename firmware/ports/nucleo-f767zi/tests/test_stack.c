/* The stack end to end over a fake link that records what it sends. */
#include "../../test-harness/harness.h"
#include "tests.h"
#include "frames.h"

#include "../net/net_arp.h"
#include "../net/net_checksum.h"
#include "../net/net_stack.h"

typedef struct {
    uint8_t frames[8][NET_ETH_MAX];
    size_t lens[8];
    unsigned count;
    int refuse;
} fake_link;

static int fake_send(void *ctx, const uint8_t *frame, size_t len)
{
    fake_link *l = ctx;
    if (l->refuse) {
        return -1;
    }
    if (l->count < 8) {
        memcpy(l->frames[l->count], frame, len);
        l->lens[l->count] = len;
    }
    l->count++;
    return 0;
}

static const uint8_t DEV_MAC[] = {DEVICE_MAC};
static const uint8_t H_MAC[] = {HOST_MAC};
static const uint8_t O_MAC[] = {OTHER_MAC};
static const uint8_t BCAST[] = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};

static net_stack stack; /* large (queue of full-size datagrams): keep off the stack */

static void setup(fake_link *link)
{
    memset(link, 0, sizeof *link);
    net_config cfg = {.mac = {DEVICE_MAC},
                      .ip = IP_DEVICE,
                      .netmask = 0xFFFFFF00u,
                      .udp_port = 47300,
                      .peer_ip = IP_HOST};
    net_stack_init(&stack, &cfg, fake_send, link);
}

/* An Ethernet frame around the reference datagram, from `src_mac` to `dst_mac`. */
static size_t udp_frame(uint8_t *f, const uint8_t *dst_mac, const uint8_t *src_mac)
{
    static const uint8_t dgram[] = {IPV4_UDP_HELLO};
    memcpy(f, dst_mac, 6);
    memcpy(f + 6, src_mac, 6);
    f[12] = 0x08;
    f[13] = 0x00;
    memcpy(f + 14, dgram, sizeof dgram);
    return 14 + sizeof dgram;
}

static void udp_in(void)
{
    fake_link link;
    setup(&link);
    uint8_t f[128];
    size_t n = udp_frame(f, DEV_MAC, H_MAC);
    /* Minimum-size frame with padding, as a real MAC delivers it. */
    memset(f + n, 0, 60 - n);
    net_stack_input(&stack, f, 60, 0);
    uint8_t buf[64];
    uint32_t ip = 0;
    uint16_t port = 0;
    CHECK_EQ(net_stack_receive(&stack, buf, sizeof buf, &ip, &port), 11);
    CHECK_BYTES(buf, "hello, exo!", 11);
    CHECK_EQ(ip, IP_HOST);
    CHECK_EQ(port, 50000u);
    CHECK_EQ(net_stack_receive(&stack, buf, sizeof buf, &ip, &port), 0);
    CHECK(stack.peer_mac_known);
    CHECK_BYTES(stack.peer_mac, H_MAC, 6);
    CHECK_EQ(link.count, 0u); /* nothing answered */

    /* A datagram longer than the caller's buffer: consumed, true length returned. */
    net_stack_input(&stack, f, 60, 0);
    CHECK_EQ(net_stack_receive(&stack, buf, 5, &ip, &port), 11);
    CHECK_EQ(net_stack_receive(&stack, buf, sizeof buf, &ip, &port), 0);

    /* Queue full: the fifth waiting datagram is dropped and counted. */
    for (int i = 0; i < NET_RXQ_LEN + 1; i++) {
        net_stack_input(&stack, f, n, 0);
    }
    CHECK_EQ(stack.stats.rx_queue_full, 1u);
    int taken = 0;
    while (net_stack_receive(&stack, buf, sizeof buf, &ip, &port) > 0) {
        taken++;
    }
    CHECK_EQ(taken, NET_RXQ_LEN);
}

static void udp_filtered(void)
{
    fake_link link;
    setup(&link);
    uint8_t f[128], buf[64];
    uint32_t ip;
    uint16_t port;
    size_t n = udp_frame(f, O_MAC, H_MAC); /* unicast to another MAC */
    net_stack_input(&stack, f, n, 0);
    CHECK_EQ(stack.stats.not_for_us, 1u);

    n = udp_frame(f, DEV_MAC, H_MAC); /* valid, but to port 47301 */
    size_t u = net_udp_build(f + 34, IP_HOST, IP_DEVICE, 50000, 47301,
                             (const uint8_t *)"hello, exo!", 11);
    net_ipv4_header(f + 14, IP_HOST, IP_DEVICE, NET_IPPROTO_UDP, 1, u);
    net_stack_input(&stack, f, n, 0);
    CHECK_EQ(stack.stats.udp_wrong_port, 1u);
    CHECK_EQ(stack.stats.udp_errors, 0u);

    n = udp_frame(f, DEV_MAC, H_MAC);
    f[n - 1] ^= 1; /* payload damage: UDP checksum */
    net_stack_input(&stack, f, n, 0);
    CHECK_EQ(stack.stats.udp_errors, 1u);

    n = udp_frame(f, DEV_MAC, H_MAC);
    f[14 + 10] ^= 1; /* IPv4 header checksum */
    net_stack_input(&stack, f, n, 0);
    CHECK_EQ(stack.stats.ipv4_errors, 1u);

    n = udp_frame(f, DEV_MAC, H_MAC);
    net_stack_input(&stack, f, 13, 0); /* runt */
    CHECK_EQ(net_stack_receive(&stack, buf, sizeof buf, &ip, &port), 0);
    CHECK_EQ(link.count, 0u);
}

static void arp_reply_and_learning(void)
{
    fake_link link;
    setup(&link);
    /* Broadcast "who has 192.168.50.2" from the host. */
    uint8_t f[60] = {0};
    memcpy(f, BCAST, 6);
    memcpy(f + 6, H_MAC, 6);
    f[12] = 0x08;
    f[13] = 0x06;
    const uint8_t req[] = {0x00, 0x01, 0x08, 0x00, 6, 4, 0x00, 0x01, HOST_MAC, 192, 168, 50, 1,
                           0,    0,    0,    0,    0, 0, 192,  168,  50,   2};
    memcpy(f + 14, req, sizeof req);
    net_stack_input(&stack, f, sizeof f, 0);
    CHECK_EQ(link.count, 1u);
    CHECK_EQ(link.lens[0], 60u);
    /* The reply, written out: to the host, from us, ARP, is-at 02:..:02. */
    const uint8_t want[] = {HOST_MAC, DEVICE_MAC, 0x08, 0x06, 0x00, 0x01, 0x08, 0x00,
                            6,        4,          0x00, 0x02, DEVICE_MAC, 192,  168,  50,
                            2,        HOST_MAC,   192,  168,  50,   1};
    CHECK_BYTES(link.frames[0], want, sizeof want);
    CHECK(stack.peer_mac_known);
    CHECK_EQ(stack.stats.arp_replies_sent, 1u);

    /* A request for someone else is not answered (but the host's MAC still counts). */
    f[14 + 27] = 9;
    net_stack_input(&stack, f, sizeof f, 0);
    CHECK_EQ(link.count, 1u);

    /* A request from another machine does not change the learned host MAC. */
    memcpy(f + 6, O_MAC, 6);
    memcpy(f + 14 + 8, O_MAC, 6);
    f[14 + 17] = 9;
    f[14 + 27] = 2;
    net_stack_input(&stack, f, sizeof f, 0);
    CHECK_EQ(link.count, 2u); /* answered */
    CHECK_BYTES(link.frames[1], O_MAC, 6);
    CHECK_BYTES(stack.peer_mac, H_MAC, 6);
    CHECK_EQ(stack.stats.peer_mac_changes, 1u);
}

static void send_needs_peer_mac(void)
{
    fake_link link;
    setup(&link);
    const uint8_t pay[] = {1, 2, 3, 4, 5};
    CHECK_EQ(net_stack_send_udp(&stack, IP_HOST, 50000, pay, sizeof pay, 1000), -1);
    CHECK_EQ(link.count, 1u); /* an ARP request went out instead */
    net_arp a;
    CHECK_BYTES(link.frames[0], BCAST, 6);
    CHECK_EQ(net_arp_parse(link.frames[0] + 14, link.lens[0] - 14, &a), 0);
    CHECK_EQ(a.oper, NET_ARP_REQUEST);
    CHECK_EQ(a.tpa, IP_HOST);
    CHECK_EQ(a.spa, IP_DEVICE);

    /* Rate limit: not again within 100 ms, again after. */
    CHECK_EQ(net_stack_send_udp(&stack, IP_HOST, 50000, pay, sizeof pay, 50000), -1);
    CHECK_EQ(link.count, 1u);
    CHECK_EQ(net_stack_send_udp(&stack, IP_HOST, 50000, pay, sizeof pay, 101000), -1);
    CHECK_EQ(link.count, 2u);

    /* Never to any other address, with or without its MAC. */
    CHECK_EQ(net_stack_send_udp(&stack, IP_OTHER, 50000, pay, sizeof pay, 500000), -1);
    CHECK_EQ(link.count, 2u);

    /* The host's ARP reply teaches its MAC; the datagram then goes out. */
    uint8_t f[60] = {0};
    memcpy(f, DEV_MAC, 6);
    memcpy(f + 6, H_MAC, 6);
    f[12] = 0x08;
    f[13] = 0x06;
    a.oper = NET_ARP_REPLY;
    memcpy(a.sha, H_MAC, 6);
    a.spa = IP_HOST;
    memcpy(a.tha, DEV_MAC, 6);
    a.tpa = IP_DEVICE;
    net_arp_build(f + 14, &a);
    net_stack_input(&stack, f, sizeof f, 0);
    CHECK_EQ(link.count, 2u);
    CHECK_EQ(net_stack_send_udp(&stack, IP_HOST, 50000, pay, sizeof pay, 600000), 0);
    CHECK_EQ(link.count, 3u);

    const uint8_t *o = link.frames[2];
    CHECK_EQ(link.lens[2], 60u); /* 14 + 20 + 8 + 5 = 47, padded */
    CHECK_BYTES(o, H_MAC, 6);
    CHECK_BYTES(o + 6, DEV_MAC, 6);
    net_ipv4 ip;
    CHECK_EQ(net_ipv4_parse(o + 14, link.lens[2] - 14, &ip), NET_IPV4_OK);
    CHECK_EQ(ip.src, IP_DEVICE);
    CHECK_EQ(ip.dst, IP_HOST);
    net_udp u;
    CHECK_EQ(net_udp_parse(ip.payload, ip.payload_len, ip.src, ip.dst, &u), NET_UDP_OK);
    CHECK_EQ(u.src_port, 47300u);
    CHECK_EQ(u.dst_port, 50000u);
    CHECK_EQ(u.len, sizeof pay);
    CHECK_BYTES(u.payload, pay, sizeof pay);
    CHECK(o[14 + 6 + 2 + 6] != 0 || o[14 + 6 + 2 + 7] != 0); /* UDP checksum present */

    /* Too long, and a link that refuses: -1, counted. */
    static uint8_t big[NET_UDP_MAX + 1];
    CHECK_EQ(net_stack_send_udp(&stack, IP_HOST, 50000, big, sizeof big, 0), -1);
    CHECK_EQ(net_stack_send_udp(&stack, IP_HOST, 50000, big, NET_UDP_MAX, 0), 0);
    CHECK_EQ(link.lens[3], (size_t)NET_ETH_MAX);
    link.refuse = 1;
    CHECK_EQ(net_stack_send_udp(&stack, IP_HOST, 50000, pay, sizeof pay, 0), -1);
    CHECK_EQ(stack.stats.tx_errors, 2u);
}

static void ping(void)
{
    fake_link link;
    setup(&link);
    uint8_t f[14 + 20 + 12];
    memcpy(f, DEV_MAC, 6);
    memcpy(f + 6, H_MAC, 6);
    f[12] = 0x08;
    f[13] = 0x00;
    const uint8_t icmp[] = {8, 0, 0, 0, 0x12, 0x34, 0x00, 0x01, 'p', 'i', 'n', 'g'};
    uint8_t *ic = f + 34;
    memcpy(ic, icmp, sizeof icmp);
    uint16_t c = net_checksum(ic, sizeof icmp);
    ic[2] = (uint8_t)(c >> 8);
    ic[3] = (uint8_t)c;
    /* From another machine: no answer (a flood of pings makes the device send nothing). */
    net_ipv4_header(f + 14, IP_OTHER, IP_DEVICE, NET_IPPROTO_ICMP, 7, sizeof icmp);
    net_stack_input(&stack, f, sizeof f, 0);
    CHECK_EQ(link.count, 0u);
    CHECK_EQ(stack.stats.not_host, 1u);

    /* From the host, answered to the frame's sender. */
    net_ipv4_header(f + 14, IP_HOST, IP_DEVICE, NET_IPPROTO_ICMP, 7, sizeof icmp);
    net_stack_input(&stack, f, sizeof f, 0);
    CHECK_EQ(link.count, 1u);
    CHECK_EQ(stack.stats.icmp_echo_replies, 1u);
    const uint8_t *o = link.frames[0];
    CHECK_BYTES(o, H_MAC, 6);
    net_ipv4 ip;
    CHECK_EQ(net_ipv4_parse(o + 14, link.lens[0] - 14, &ip), NET_IPV4_OK);
    CHECK_EQ(ip.dst, IP_HOST);
    CHECK_EQ(ip.proto, NET_IPPROTO_ICMP);
    CHECK_EQ(ip.payload_len, sizeof icmp);
    CHECK_EQ(ip.payload[0], 0u); /* echo reply */
    CHECK_EQ(net_checksum(ip.payload, ip.payload_len), 0u);
    CHECK_BYTES(ip.payload + 4, icmp + 4, sizeof icmp - 4);

    /* A damaged request gets no answer. */
    ic[9] ^= 1;
    net_stack_input(&stack, f, sizeof f, 0);
    CHECK_EQ(link.count, 1u);
}

void test_stack(void)
{
    udp_in();
    udp_filtered();
    arp_reply_and_learning();
    send_needs_peer_mac();
    ping();
}
