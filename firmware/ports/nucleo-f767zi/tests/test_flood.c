/* Floods: datagrams and pings from any source but the host never reach the queue,
 * cost no checksum, get no answer, and never displace a datagram of the host's. */
#include "../../test-harness/harness.h"
#include "tests.h"
#include "frames.h"

#include "../net/net_stack.h"

static int no_send(void *ctx, const uint8_t *frame, size_t len)
{
    (void)ctx;
    (void)frame;
    (void)len;
    return 0;
}

static net_stack stack; /* large: keep off the stack */

static void setup(void)
{
    net_config cfg = {.mac = {DEVICE_MAC},
                      .ip = IP_DEVICE,
                      .netmask = 0xFFFFFF00u,
                      .udp_port = 47300,
                      .peer_ip = IP_HOST};
    net_stack_init(&stack, &cfg, no_send, 0);
}

/* A valid Ethernet/IPv4/UDP frame to the device's port from `src_ip`, whose payload
 * is the one byte `tag` repeated `len` times. */
static size_t frame_from(uint8_t *f, uint32_t src_ip, uint8_t tag, size_t len)
{
    static const uint8_t dev_mac[] = {DEVICE_MAC};
    static const uint8_t host_mac[] = {HOST_MAC};
    uint8_t payload[64];
    memset(payload, tag, len);
    memcpy(f, dev_mac, 6);
    memcpy(f + 6, host_mac, 6);
    f[12] = 0x08;
    f[13] = 0x00;
    size_t u = net_udp_build(f + 34, src_ip, IP_DEVICE, 50000, 47300, payload, len);
    net_ipv4_header(f + 14, src_ip, IP_DEVICE, NET_IPPROTO_UDP, 1, u);
    return 34 + u;
}

static void foreign_source_dropped_before_queue(void)
{
    setup();
    uint8_t f[128], buf[64];
    uint32_t ip = 0;
    uint16_t port = 0;
    size_t n = frame_from(f, IP_OTHER, 0xAA, 20);
    net_stack_input(&stack, f, n, 0);
    CHECK_EQ(stack.stats.not_host, 1u);
    CHECK_EQ(stack.rx_count, 0u);
    CHECK_EQ(net_stack_receive(&stack, buf, sizeof buf, &ip, &port), 0);

    /* Dropped before its checksum is computed: a damaged one counts the same way. */
    f[n - 1] ^= 1;
    net_stack_input(&stack, f, n, 0);
    CHECK_EQ(stack.stats.not_host, 2u);
    CHECK_EQ(stack.stats.udp_errors, 0u);

    /* The host's datagram still gets through, and the host's MAC is all that was
     * learned (the foreign frames carried the host's MAC but another IP). */
    n = frame_from(f, IP_HOST, 0x11, 20);
    net_stack_input(&stack, f, n, 0);
    CHECK_EQ(net_stack_receive(&stack, buf, sizeof buf, &ip, &port), 20);
    CHECK_EQ(ip, IP_HOST);
    CHECK_EQ(buf[0], 0x11u);
    CHECK_EQ(stack.stats.peer_mac_changes, 1u);
}

static void flood_never_displaces_host_datagrams(void)
{
    setup();
    uint8_t f[128], buf[64];
    uint32_t ip = 0;
    uint16_t port = 0;
    /* The queue full of the host's datagrams, then a flood from another machine. */
    for (uint8_t i = 0; i < NET_RXQ_LEN; i++) {
        size_t n = frame_from(f, IP_HOST, (uint8_t)(0x20u + i), 10);
        net_stack_input(&stack, f, n, 0);
    }
    for (int i = 0; i < 10000; i++) {
        size_t n = frame_from(f, IP_OTHER, 0xEE, 10);
        net_stack_input(&stack, f, n, 0);
    }
    CHECK_EQ(stack.stats.not_host, 10000u);
    CHECK_EQ(stack.stats.rx_queue_full, 0u); /* not even counted as a queue overflow */
    for (uint8_t i = 0; i < NET_RXQ_LEN; i++) {
        CHECK_EQ(net_stack_receive(&stack, buf, sizeof buf, &ip, &port), 10);
        CHECK_EQ(ip, IP_HOST);
        CHECK_EQ(buf[0], (uint8_t)(0x20u + i)); /* all of them, in order */
    }
    CHECK_EQ(net_stack_receive(&stack, buf, sizeof buf, &ip, &port), 0);
}

static void host_datagrams_all_delivered_through_a_flood(void)
{
    setup();
    uint8_t f[128], buf[64];
    uint32_t ip = 0;
    uint16_t port = 0;
    /* 100 foreign datagrams between each of the host's, the core taking one per
     * period: every datagram of the host's is delivered, none is lost. */
    int delivered = 0;
    for (int period = 0; period < 200; period++) {
        for (int i = 0; i < 100; i++) {
            size_t n = frame_from(f, IP_OTHER, 0xEE, 30);
            net_stack_input(&stack, f, n, 0);
        }
        size_t n = frame_from(f, IP_HOST, (uint8_t)period, 30);
        net_stack_input(&stack, f, n, 0);
        long got = net_stack_receive(&stack, buf, sizeof buf, &ip, &port);
        if (got == 30 && ip == IP_HOST && buf[0] == (uint8_t)period) {
            delivered++;
        }
    }
    CHECK_EQ(delivered, 200);
    CHECK_EQ(stack.stats.not_host, 20000u);
    CHECK_EQ(stack.stats.rx_queue_full, 0u);
}

void test_flood(void)
{
    foreign_source_dropped_before_queue();
    flood_never_displaces_host_datagrams();
    host_datagrams_all_delivered_through_a_flood();
}
