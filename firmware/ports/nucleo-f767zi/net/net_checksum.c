/* net_checksum.c - RFC 1071 one's-complement sum. */
#include "net_checksum.h"

uint32_t net_sum(uint32_t sum, const uint8_t *data, size_t len)
{
    size_t i = 0;
    for (; i + 1 < len; i += 2) {
        sum += (uint32_t)data[i] << 8 | data[i + 1];
        /* Fold early so that the 32-bit sum cannot overflow on long inputs. */
        if (sum & 0x80000000u) {
            sum = (sum & 0xFFFFu) + (sum >> 16);
        }
    }
    if (i < len) {
        sum += (uint32_t)data[i] << 8;
    }
    return sum;
}

uint16_t net_fold(uint32_t sum)
{
    while (sum >> 16) {
        sum = (sum & 0xFFFFu) + (sum >> 16);
    }
    return (uint16_t)~sum;
}

uint16_t net_checksum(const uint8_t *data, size_t len)
{
    return net_fold(net_sum(0, data, len));
}
