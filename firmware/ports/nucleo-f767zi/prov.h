/*
 * prov.h - the provisioning block: the link key and the addresses, kept in flash
 * apart from the program so that one firmware image serves every device and a
 * re-flash of the program keeps the key.
 *
 * Layout (64 bytes; multi-byte integers little-endian, IPv4 addresses as their four
 * dotted-quad bytes in order, so that a hex dump reads naturally):
 *
 *   offset size field
 *        0    4 magic "EXPV"
 *        4    2 format version, 1
 *        6    2 block size, 64
 *        8   32 link key (the 32 bytes whose 64 hex digits are the host's key file)
 *       40    4 device IPv4 address
 *       44    4 netmask
 *       48    4 host IPv4 address (the only source acted on)
 *       52    6 device MAC address (unicast)
 *       58    2 UDP port the device listens on
 *       60    4 CRC-32 (IEEE) of bytes 0..59
 *
 * Erased flash reads 0xFF everywhere, which fails the magic check: an unprovisioned
 * board never joins the network and never energises a solenoid.
 */
#ifndef PROV_H
#define PROV_H

#include <stddef.h>
#include <stdint.h>

#define PROV_SIZE 64u
#define PROV_VERSION 1u
#define PROV_KEY_BYTES 32u

typedef struct {
    uint8_t key[PROV_KEY_BYTES];
    uint32_t device_ip; /* host byte order: 192.168.1.2 is 0xC0A80102 */
    uint32_t netmask;
    uint32_t host_ip;
    uint8_t mac[6];
    uint16_t udp_port;
} prov_block;

typedef enum {
    PROV_OK = 0,
    PROV_SHORT,        /* fewer than PROV_SIZE bytes */
    PROV_MAGIC,        /* not "EXPV": erased or never written */
    PROV_VERSION_BAD,  /* a format this firmware does not read */
    PROV_SIZE_BAD,
    PROV_CRC,          /* damaged or partly written */
    PROV_KEY,          /* key all zero or all 0xFF */
    PROV_NETMASK,      /* not a contiguous mask of 8..30 bits */
    PROV_DEVICE_IP,    /* zero, or the network or broadcast address of its subnet */
    PROV_HOST_IP,      /* zero, equal to the device's, or on another subnet */
    PROV_MAC,          /* multicast or all zero */
    PROV_PORT          /* zero */
} prov_error;

/* Check and decode the block at `data`. */
prov_error prov_parse(const uint8_t *data, size_t len, prov_block *out);

/* Encode `b` into PROV_SIZE bytes at `out` (the CRC included). The caller validates
 * by parsing the result. */
void prov_write(const prov_block *b, uint8_t out[PROV_SIZE]);

/* A short English name for an error, for tools and logs. */
const char *prov_error_name(prov_error e);

#endif /* PROV_H */
