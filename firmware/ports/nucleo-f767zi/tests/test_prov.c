/* The provisioning block: CRC-32 reference value, round trip, every refusal. */
#include "../../test-harness/harness.h"
#include "tests.h"

#include "../crc32.h"
#include "../prov.h"

static prov_block sample(void)
{
    prov_block b;
    for (unsigned i = 0; i < PROV_KEY_BYTES; i++) {
        b.key[i] = (uint8_t)i; /* the protocol's test-vector key 00 01 .. 1f */
    }
    b.device_ip = 0xC0A83202u;
    b.netmask = 0xFFFFFF00u;
    b.host_ip = 0xC0A83201u;
    const uint8_t mac[6] = {0x02, 0x45, 0x58, 0x00, 0x00, 0x02};
    memcpy(b.mac, mac, 6);
    b.udp_port = 47300;
    return b;
}

/* Re-encode with one field changed (CRC recomputed), expect `want`. */
static void expect(prov_block b, prov_error want)
{
    uint8_t raw[PROV_SIZE];
    prov_block out;
    prov_write(&b, raw);
    CHECK_EQ(prov_parse(raw, sizeof raw, &out), want);
}

void test_prov(void)
{
    /* The CRC-32 check value from the catalogue of parametrised CRCs. */
    CHECK_EQ(crc32_ieee((const uint8_t *)"123456789", 9), 0xCBF43926u);

    prov_block b = sample(), out;
    uint8_t raw[PROV_SIZE];
    prov_write(&b, raw);
    /* Layout spot checks against prov.h's table. */
    CHECK_BYTES(raw, "EXPV", 4);
    CHECK_EQ(raw[4] | raw[5] << 8, 1);
    CHECK_EQ(raw[6] | raw[7] << 8, 64);
    CHECK_EQ(raw[8 + 31], 0x1Fu);
    const uint8_t ip[4] = {192, 168, 50, 2};
    CHECK_BYTES(raw + 40, ip, 4);
    CHECK_EQ(raw[58] | raw[59] << 8, 47300);

    memset(&out, 0, sizeof out);
    CHECK_EQ(prov_parse(raw, sizeof raw, &out), PROV_OK);
    CHECK_BYTES(out.key, b.key, PROV_KEY_BYTES);
    CHECK_EQ(out.device_ip, b.device_ip);
    CHECK_EQ(out.netmask, b.netmask);
    CHECK_EQ(out.host_ip, b.host_ip);
    CHECK_BYTES(out.mac, b.mac, 6);
    CHECK_EQ(out.udp_port, 47300u);

    CHECK_EQ(prov_parse(raw, PROV_SIZE - 1, &out), PROV_SHORT);

    /* Erased flash, and every single-bit flip of a good block, are refused. */
    uint8_t erased[PROV_SIZE];
    memset(erased, 0xFF, sizeof erased);
    CHECK_EQ(prov_parse(erased, sizeof erased, &out), PROV_MAGIC);
    int all_refused = 1;
    for (unsigned bit = 0; bit < PROV_SIZE * 8; bit++) {
        uint8_t bad[PROV_SIZE];
        memcpy(bad, raw, sizeof bad);
        bad[bit / 8] ^= (uint8_t)(1u << (bit % 8));
        if (prov_parse(bad, sizeof bad, &out) == PROV_OK) {
            all_refused = 0;
        }
    }
    CHECK(all_refused);

    uint8_t bad[PROV_SIZE];
    memcpy(bad, raw, sizeof bad);
    bad[4] = 2;
    CHECK_EQ(prov_parse(bad, sizeof bad, &out), PROV_VERSION_BAD);
    memcpy(bad, raw, sizeof bad);
    bad[6] = 65;
    CHECK_EQ(prov_parse(bad, sizeof bad, &out), PROV_SIZE_BAD);
    memcpy(bad, raw, sizeof bad);
    bad[20] ^= 1;
    CHECK_EQ(prov_parse(bad, sizeof bad, &out), PROV_CRC);

    prov_block c = sample();
    memset(c.key, 0, sizeof c.key);
    expect(c, PROV_KEY);
    memset(c.key, 0xFF, sizeof c.key);
    expect(c, PROV_KEY);

    c = sample();
    c.netmask = 0xFFFF00FFu;
    expect(c, PROV_NETMASK);
    c.netmask = 0xFFFFFFFFu;
    expect(c, PROV_NETMASK);
    c.netmask = 0xFE000000u; /* /7 */
    expect(c, PROV_NETMASK);
    c.netmask = 0xFFFFFFFCu; /* /30 is the smallest allowed */
    c.device_ip = 0xC0A83201u;
    c.host_ip = 0xC0A83202u;
    expect(c, PROV_OK);

    c = sample();
    c.device_ip = 0xC0A83200u;
    expect(c, PROV_DEVICE_IP);
    c.device_ip = 0xC0A832FFu;
    expect(c, PROV_DEVICE_IP);
    c.device_ip = 0;
    expect(c, PROV_DEVICE_IP);

    c = sample();
    c.host_ip = c.device_ip;
    expect(c, PROV_HOST_IP);
    c.host_ip = 0xC0A83301u; /* 192.168.51.1: other subnet */
    expect(c, PROV_HOST_IP);
    c.host_ip = 0xC0A832FFu;
    expect(c, PROV_HOST_IP);
    c.host_ip = 0;
    expect(c, PROV_HOST_IP);

    c = sample();
    c.mac[0] = 0x03;
    expect(c, PROV_MAC);
    memset(c.mac, 0, 6);
    expect(c, PROV_MAC);

    c = sample();
    c.udp_port = 0;
    expect(c, PROV_PORT);

    CHECK(strcmp(prov_error_name(PROV_CRC), prov_error_name(PROV_MAGIC)) != 0);
}
