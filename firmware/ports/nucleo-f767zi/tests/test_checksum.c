/* Internet checksum against published examples. */
#include "../../test-harness/harness.h"
#include "tests.h"

#include "../net/net_checksum.h"

void test_checksum(void)
{
    /* RFC 1071 section 3 worked example: the sum of these bytes is 0xddf2. */
    const uint8_t rfc[] = {0x00, 0x01, 0xf2, 0x03, 0xf4, 0xf5, 0xf6, 0xf7};
    CHECK_EQ(net_fold(net_sum(0, rfc, sizeof rfc)), (uint16_t)~0xddf2u);

    /* A widely reproduced IPv4 header (192.168.0.1 -> 192.168.0.199, UDP) whose stored
     * checksum is 0xb861: with the field zeroed the checksum must come out as 0xb861,
     * and the header as sent must check to 0. */
    uint8_t hdr[] = {0x45, 0x00, 0x00, 0x73, 0x00, 0x00, 0x40, 0x00, 0x40, 0x11,
                     0xb8, 0x61, 0xc0, 0xa8, 0x00, 0x01, 0xc0, 0xa8, 0x00, 0xc7};
    CHECK_EQ(net_checksum(hdr, sizeof hdr), 0u);
    hdr[10] = hdr[11] = 0;
    CHECK_EQ(net_checksum(hdr, sizeof hdr), 0xb861u);

    /* Odd length: the last byte is padded with zero. */
    const uint8_t odd[] = {0x01, 0x02, 0x03};
    CHECK_EQ(net_checksum(odd, sizeof odd), (uint16_t)~(0x0102u + 0x0300u));

    /* Summing in pieces (even-length pieces) equals summing at once. */
    uint8_t big[1000];
    for (unsigned i = 0; i < sizeof big; i++) {
        big[i] = (uint8_t)(i * 37u + 11u);
    }
    uint32_t s = net_sum(0, big, 400);
    s = net_sum(s, big + 400, 600);
    CHECK_EQ(net_fold(s), net_checksum(big, sizeof big));

    /* All 0xFF bytes over a long block: the early folding must not overflow. */
    static uint8_t ones[70000];
    memset(ones, 0xFF, sizeof ones);
    CHECK_EQ(net_checksum(ones, sizeof ones), 0u);
}
