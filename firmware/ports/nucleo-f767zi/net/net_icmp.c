/* net_icmp.c - answer ICMP echo requests. */
#include "net_icmp.h"

#include "net_bytes.h"
#include "net_checksum.h"

#define ICMP_ECHO_REPLY 0u
#define ICMP_ECHO_REQUEST 8u

size_t net_icmp_echo_reply(uint8_t *out, const uint8_t *in, size_t len)
{
    if (len < 8u || in[0] != ICMP_ECHO_REQUEST || in[1] != 0u || net_checksum(in, len) != 0u) {
        return 0u;
    }
    net_copy(out, in, (unsigned)len);
    out[0] = ICMP_ECHO_REPLY;
    net_put16(out + 2, 0u);
    net_put16(out + 2, net_checksum(out, len));
    return len;
}
