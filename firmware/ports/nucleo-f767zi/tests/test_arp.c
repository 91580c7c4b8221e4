/* ARP: parse a request written out byte by byte, build it back. */
#include "../../test-harness/harness.h"
#include "tests.h"
#include "frames.h"

#include "../net/net_arp.h"

/* Who has 192.168.50.2? Tell 192.168.50.1 (at 02:00:00:00:00:01). */
static const uint8_t REQUEST[] = {0x00, 0x01, 0x08, 0x00, 6,    4,    0x00, 0x01, HOST_MAC,
                                  192,  168,  50,   1,    0x00, 0x00, 0x00, 0x00, 0x00,
                                  0x00, 192,  168,  50,   2};

void test_arp(void)
{
    net_arp a;
    CHECK_EQ(sizeof REQUEST, (size_t)NET_ARP_LEN);
    CHECK_EQ(net_arp_parse(REQUEST, sizeof REQUEST, &a), 0);
    CHECK_EQ(a.oper, NET_ARP_REQUEST);
    CHECK_EQ(a.spa, IP_HOST);
    CHECK_EQ(a.tpa, IP_DEVICE);
    const uint8_t host[] = {HOST_MAC};
    CHECK_BYTES(a.sha, host, 6);

    uint8_t out[NET_ARP_LEN];
    CHECK_EQ(net_arp_build(out, &a), (size_t)NET_ARP_LEN);
    CHECK_BYTES(out, REQUEST, sizeof REQUEST);

    uint8_t bad[NET_ARP_LEN];
    CHECK_EQ(net_arp_parse(REQUEST, NET_ARP_LEN - 1, &a), -1);
    const unsigned fields[] = {1, 3, 4, 5, 7};
    for (unsigned i = 0; i < sizeof fields / sizeof fields[0]; i++) {
        memcpy(bad, REQUEST, sizeof bad);
        bad[fields[i]] ^= 0x10; /* hardware type, protocol, lengths, operation */
        CHECK_EQ(net_arp_parse(bad, sizeof bad, &a), -1);
    }
}
