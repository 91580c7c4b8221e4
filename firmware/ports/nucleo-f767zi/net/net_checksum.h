/*
 * net_checksum.h - the Internet checksum (RFC 1071) used by IPv4, ICMP and UDP.
 *
 * Kept as a running 32-bit sum so that the UDP pseudo-header and the datagram, which
 * are not contiguous in memory, can be summed in pieces and folded once at the end.
 */
#ifndef NET_CHECKSUM_H
#define NET_CHECKSUM_H

#include <stddef.h>
#include <stdint.h>

/* Add `len` bytes to `sum` as big-endian 16-bit words. An odd trailing byte is padded
 * with a zero byte, so only the last piece of a sum may have an odd length. */
uint32_t net_sum(uint32_t sum, const uint8_t *data, size_t len);

/* Fold the carries and take the one's complement: the value to store in a header. A
 * header whose stored checksum is right sums (with net_sum) and folds to 0. */
uint16_t net_fold(uint32_t sum);

/* The checksum of one contiguous block. */
uint16_t net_checksum(const uint8_t *data, size_t len);

#endif /* NET_CHECKSUM_H */
