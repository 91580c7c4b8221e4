/* IPv4 and UDP: parse a reference datagram, reject each kind of damage, rebuild it. */
#include "../../test-harness/harness.h"
#include "tests.h"
#include "frames.h"

#include "../net/net_checksum.h"
#include "../net/net_ipv4.h"
#include "../net/net_udp.h"

static const uint8_t REF[] = {IPV4_UDP_HELLO};

static void parse_reference(void)
{
    net_ipv4 ip;
    CHECK_EQ(net_ipv4_parse(REF, sizeof REF, &ip), NET_IPV4_OK);
    CHECK_EQ(ip.src, IP_HOST);
    CHECK_EQ(ip.dst, IP_DEVICE);
    CHECK_EQ(ip.proto, NET_IPPROTO_UDP);
    CHECK_EQ(ip.payload_len, 19u);
    net_udp u;
    CHECK_EQ(net_udp_parse(ip.payload, ip.payload_len, ip.src, ip.dst, &u), NET_UDP_OK);
    CHECK_EQ(u.src_port, 50000u);
    CHECK_EQ(u.dst_port, 47300u);
    CHECK_EQ(u.len, 11u);
    CHECK_BYTES(u.payload, "hello, exo!", 11);

    /* Ethernet padding after the datagram is ignored (total length rules). */
    uint8_t padded[sizeof REF + 7];
    memcpy(padded, REF, sizeof REF);
    memset(padded + sizeof REF, 0xAA, 7);
    CHECK_EQ(net_ipv4_parse(padded, sizeof padded, &ip), NET_IPV4_OK);
    CHECK_EQ(ip.payload_len, 19u);
}

static void ipv4_errors(void)
{
    net_ipv4 ip;
    uint8_t b[sizeof REF];
    CHECK_EQ(net_ipv4_parse(REF, 19, &ip), NET_IPV4_SHORT);

    memcpy(b, REF, sizeof b);
    b[0] = 0x65;
    CHECK_EQ(net_ipv4_parse(b, sizeof b, &ip), NET_IPV4_VERSION);

    memcpy(b, REF, sizeof b);
    b[0] = 0x44;
    CHECK_EQ(net_ipv4_parse(b, sizeof b, &ip), NET_IPV4_HEADER_LENGTH);
    b[0] = 0x4F; /* 60-byte header in a 39-byte packet */
    CHECK_EQ(net_ipv4_parse(b, sizeof b, &ip), NET_IPV4_HEADER_LENGTH);

    memcpy(b, REF, sizeof b);
    b[3] = 0x28; /* claims one byte more than there is */
    CHECK_EQ(net_ipv4_parse(b, sizeof b, &ip), NET_IPV4_TOTAL_LENGTH);

    /* Every single-bit flip in the header is caught (by some check). */
    int all_caught = 1;
    for (unsigned bit = 0; bit < 20 * 8; bit++) {
        memcpy(b, REF, sizeof b);
        b[bit / 8] ^= (uint8_t)(1u << (bit % 8));
        if (net_ipv4_parse(b, sizeof b, &ip) == NET_IPV4_OK) {
            all_caught = 0;
        }
    }
    CHECK(all_caught);

    /* Fragments, with the checksum made valid again so only the fragment check fires. */
    memcpy(b, REF, sizeof b);
    b[6] = 0x20; /* more fragments */
    b[7] = 0x00;
    b[10] = b[11] = 0;
    uint16_t c = net_checksum(b, 20);
    b[10] = (uint8_t)(c >> 8);
    b[11] = (uint8_t)c;
    CHECK_EQ(net_ipv4_parse(b, sizeof b, &ip), NET_IPV4_FRAGMENT);
    b[6] = 0x00;
    b[7] = 0x08; /* offset 8, last fragment */
    b[10] = b[11] = 0;
    c = net_checksum(b, 20);
    b[10] = (uint8_t)(c >> 8);
    b[11] = (uint8_t)c;
    CHECK_EQ(net_ipv4_parse(b, sizeof b, &ip), NET_IPV4_FRAGMENT);
}

static void udp_errors(void)
{
    net_udp u;
    uint8_t d[19];
    memcpy(d, REF + 20, sizeof d);
    CHECK_EQ(net_udp_parse(d, 7, IP_HOST, IP_DEVICE, &u), NET_UDP_SHORT);
    d[5] = 20; /* length beyond the IP payload */
    CHECK_EQ(net_udp_parse(d, sizeof d, IP_HOST, IP_DEVICE, &u), NET_UDP_LENGTH);
    d[5] = 7;
    CHECK_EQ(net_udp_parse(d, sizeof d, IP_HOST, IP_DEVICE, &u), NET_UDP_LENGTH);

    /* Payload damage, and a wrong pseudo-header (another source), fail the checksum. */
    memcpy(d, REF + 20, sizeof d);
    d[12] ^= 0x04;
    CHECK_EQ(net_udp_parse(d, sizeof d, IP_HOST, IP_DEVICE, &u), NET_UDP_CHECKSUM);
    memcpy(d, REF + 20, sizeof d);
    CHECK_EQ(net_udp_parse(d, sizeof d, IP_OTHER, IP_DEVICE, &u), NET_UDP_CHECKSUM);

    /* Checksum 0 means none was computed: accepted as is. */
    d[6] = d[7] = 0;
    d[12] ^= 0x04;
    CHECK_EQ(net_udp_parse(d, sizeof d, IP_OTHER, IP_DEVICE, &u), NET_UDP_OK);
}

static void build_matches_reference(void)
{
    uint8_t out[sizeof REF];
    size_t n = net_udp_build(out + 20, IP_HOST, IP_DEVICE, 50000, 47300,
                             (const uint8_t *)"hello, exo!", 11);
    CHECK_EQ(n, 19u);
    CHECK_EQ(net_ipv4_header(out, IP_HOST, IP_DEVICE, NET_IPPROTO_UDP, 0x1234, n), 20u);
    CHECK_BYTES(out, REF, sizeof REF);

    /* A payload whose checksum computes to 0 goes out as 0xFFFF, never 0. Two bytes
     * chosen so that the whole sum is 0xFFFF: find them by trying. */
    int found = 0, never_zero = 1;
    for (unsigned v = 0; v <= 0xFFFFu && !found; v++) {
        uint8_t pay[2] = {(uint8_t)(v >> 8), (uint8_t)v};
        uint8_t u[10];
        net_udp_build(u, IP_HOST, IP_DEVICE, 1, 2, pay, 2);
        if (u[6] == 0xFF && u[7] == 0xFF) {
            net_udp parsed;
            found = 1;
            CHECK_EQ(net_udp_parse(u, sizeof u, IP_HOST, IP_DEVICE, &parsed), NET_UDP_OK);
        }
        if (u[6] == 0 && u[7] == 0) {
            never_zero = 0;
        }
    }
    CHECK(found);
    CHECK(never_zero);
}

void test_ipv4_udp(void)
{
    parse_reference();
    ipv4_errors();
    udp_errors();
    build_matches_reference();
}
