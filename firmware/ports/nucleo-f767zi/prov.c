/* prov.c - encode and check the provisioning block (layout in prov.h). */
#include "prov.h"

#include "crc32.h"

static uint32_t get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put_le32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static uint32_t get_ip(const uint8_t *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

static void put_ip(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24);
    p[1] = (uint8_t)(v >> 16);
    p[2] = (uint8_t)(v >> 8);
    p[3] = (uint8_t)v;
}

static int all_bytes(const uint8_t *p, size_t n, uint8_t v)
{
    for (size_t i = 0; i < n; i++) {
        if (p[i] != v) {
            return 0;
        }
    }
    return 1;
}

static int mask_bits(uint32_t mask)
{
    /* A contiguous mask is ones then zeros: ~mask + 1 is then a power of two. */
    uint32_t inv = ~mask;
    if ((inv & (inv + 1u)) != 0u) {
        return -1;
    }
    int bits = 0;
    while (mask & 0x80000000u) {
        bits++;
        mask <<= 1;
    }
    return bits;
}

prov_error prov_parse(const uint8_t *d, size_t len, prov_block *out)
{
    if (len < PROV_SIZE) {
        return PROV_SHORT;
    }
    if (d[0] != 'E' || d[1] != 'X' || d[2] != 'P' || d[3] != 'V') {
        return PROV_MAGIC;
    }
    if ((d[4] | d[5] << 8) != PROV_VERSION) {
        return PROV_VERSION_BAD;
    }
    if ((d[6] | d[7] << 8) != PROV_SIZE) {
        return PROV_SIZE_BAD;
    }
    if (crc32_ieee(d, 60) != get_le32(d + 60)) {
        return PROV_CRC;
    }
    const uint8_t *key = d + 8;
    if (all_bytes(key, PROV_KEY_BYTES, 0x00) || all_bytes(key, PROV_KEY_BYTES, 0xFF)) {
        return PROV_KEY;
    }
    uint32_t dev = get_ip(d + 40), mask = get_ip(d + 44), host = get_ip(d + 48);
    int bits = mask_bits(mask);
    if (bits < 8 || bits > 30) {
        return PROV_NETMASK;
    }
    if (dev == 0u || (dev & ~mask) == 0u || (dev & ~mask) == ~mask) {
        return PROV_DEVICE_IP;
    }
    if (host == 0u || host == dev || (host & mask) != (dev & mask) || (host & ~mask) == 0u ||
        (host & ~mask) == ~mask) {
        return PROV_HOST_IP;
    }
    const uint8_t *mac = d + 52;
    if ((mac[0] & 1u) != 0u || all_bytes(mac, 6, 0x00)) {
        return PROV_MAC;
    }
    uint16_t port = (uint16_t)(d[58] | d[59] << 8);
    if (port == 0u) {
        return PROV_PORT;
    }
    for (unsigned i = 0; i < PROV_KEY_BYTES; i++) {
        out->key[i] = key[i];
    }
    out->device_ip = dev;
    out->netmask = mask;
    out->host_ip = host;
    for (unsigned i = 0; i < 6; i++) {
        out->mac[i] = mac[i];
    }
    out->udp_port = port;
    return PROV_OK;
}

void prov_write(const prov_block *b, uint8_t out[PROV_SIZE])
{
    for (unsigned i = 0; i < PROV_SIZE; i++) {
        out[i] = 0u;
    }
    out[0] = 'E';
    out[1] = 'X';
    out[2] = 'P';
    out[3] = 'V';
    out[4] = (uint8_t)PROV_VERSION;
    out[6] = (uint8_t)PROV_SIZE;
    for (unsigned i = 0; i < PROV_KEY_BYTES; i++) {
        out[8 + i] = b->key[i];
    }
    put_ip(out + 40, b->device_ip);
    put_ip(out + 44, b->netmask);
    put_ip(out + 48, b->host_ip);
    for (unsigned i = 0; i < 6; i++) {
        out[52 + i] = b->mac[i];
    }
    out[58] = (uint8_t)b->udp_port;
    out[59] = (uint8_t)(b->udp_port >> 8);
    put_le32(out + 60, crc32_ieee(out, 60));
}

const char *prov_error_name(prov_error e)
{
    switch (e) {
    case PROV_OK: return "ok";
    case PROV_SHORT: return "block shorter than 64 bytes";
    case PROV_MAGIC: return "no provisioning block (magic is not EXPV; erased flash?)";
    case PROV_VERSION_BAD: return "unknown provisioning format version";
    case PROV_SIZE_BAD: return "wrong block size field";
    case PROV_CRC: return "CRC mismatch (damaged or partly written block)";
    case PROV_KEY: return "link key is all zero or all 0xFF";
    case PROV_NETMASK: return "netmask is not a contiguous /8../30 mask";
    case PROV_DEVICE_IP: return "device IP is zero or its subnet's network/broadcast address";
    case PROV_HOST_IP: return "host IP is zero, the device's own, or on another subnet";
    case PROV_MAC: return "MAC address is multicast or all zero";
    case PROV_PORT: return "UDP port is zero";
    }
    return "unknown error";
}
