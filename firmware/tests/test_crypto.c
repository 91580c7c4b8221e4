/*
 * test_crypto.c - SHA-256 against FIPS 180-4's examples and HMAC-SHA256 against
 * RFC 4231's test cases 1-7; the constant-time comparison's results.
 */
#include <string.h>

#include "check.h"
#include "hmac.h"
#include "sha256.h"

static void check_sha(const uint8_t *data, size_t len, const char *want_hex)
{
    uint8_t want[32], got[32];
    hex_bytes(want_hex, want, sizeof want);
    exo_sha256(data, len, got);
    CHECK_BYTES(got, want, 32);
}

static void sha256_vectors(void)
{
    const char *abc = "abc";
    check_sha((const uint8_t *)abc, 3,
              "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    check_sha((const uint8_t *)"", 0,
              "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
    const char *m448 = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
    check_sha((const uint8_t *)m448, strlen(m448),
              "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");

    /* One million 'a', fed in uneven pieces so partial blocks are exercised. */
    uint8_t a[997];
    memset(a, 'a', sizeof a);
    exo_sha256_ctx c;
    exo_sha256_init(&c);
    size_t left = 1000000, piece = 1;
    while (left > 0) {
        size_t n = piece < left ? piece : left;
        if (n > sizeof a)
            n = sizeof a;
        exo_sha256_update(&c, a, n);
        left -= n;
        piece = piece % sizeof a + 7;
    }
    uint8_t got[32], want[32];
    exo_sha256_final(&c, got);
    hex_bytes("cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0", want, 32);
    CHECK_BYTES(got, want, 32);

    /* Padding boundaries: 55, 56 and 64 bytes, streamed vs one-shot must agree, and
     * the 56-byte case (length needs a second block) against its known digest. */
    uint8_t buf[64];
    memset(buf, 'a', sizeof buf);
    check_sha(buf, 56, "b35439a4ac6f0948b6d6f9e3c6af0f5f590ce20f1bde7090ef7970686ec6738a");
    for (size_t n = 0; n <= 64; n++) {
        uint8_t one[32], two[32];
        exo_sha256(buf, n, one);
        exo_sha256_init(&c);
        exo_sha256_update(&c, buf, n / 2);
        exo_sha256_update(&c, buf + n / 2, n - n / 2);
        exo_sha256_final(&c, two);
        CHECK(memcmp(one, two, 32) == 0);
    }
}

static void check_hmac(const uint8_t *key, size_t key_len, const uint8_t *data, size_t len,
                       const char *want_hex, size_t prefix)
{
    uint8_t want[32], got[32];
    size_t n = hex_bytes(want_hex, want, sizeof want);
    CHECK_EQ(n, prefix);
    exo_hmac_key k;
    exo_hmac_set_key(&k, key, key_len);
    exo_hmac_sha256(&k, data, len, NULL, 0, got);
    CHECK_BYTES(got, want, prefix);
    /* The two-part form must give the same tag for every split point. */
    for (size_t split = 0; split <= len; split += len / 5 + 1) {
        uint8_t again[32];
        exo_hmac_sha256(&k, data, split, data + split, len - split, again);
        CHECK(memcmp(again, got, 32) == 0);
    }
}

static void rfc4231(void)
{
    uint8_t key[131], data[152];
    /* Test case 1 */
    memset(key, 0x0b, 20);
    check_hmac(key, 20, (const uint8_t *)"Hi There", 8,
               "b0344c61d8db38535ca8afceaf0bf12b881dc200c9833da726e9376c2e32cff7", 32);
    /* Test case 2: a key shorter than the output */
    const char *jefe_data = "what do ya want for nothing?";
    check_hmac((const uint8_t *)"Jefe", 4, (const uint8_t *)jefe_data, strlen(jefe_data),
               "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843", 32);
    /* Test case 3: 50 bytes of 0xdd */
    memset(key, 0xaa, 20);
    memset(data, 0xdd, 50);
    check_hmac(key, 20, data, 50,
               "773ea91e36800e46854db8ebd09181a72959098b3ef8c122d9635514ced565fe", 32);
    /* Test case 4: key 0x01..0x19 */
    for (unsigned i = 0; i < 25; i++)
        key[i] = (uint8_t)(i + 1);
    memset(data, 0xcd, 50);
    check_hmac(key, 25, data, 50,
               "82558a389a443c0ea4cc819899f2083a85f0faa3e578f8077a2e3ff46729665b", 32);
    /* Test case 5: output truncated to 128 bits (checked as a prefix) */
    memset(key, 0x0c, 20);
    check_hmac(key, 20, (const uint8_t *)"Test With Truncation", 20,
               "a3b6167473100ee06e0c796c2955552b", 16);
    /* Test case 6: a key longer than a block (hashed first) */
    memset(key, 0xaa, 131);
    const char *t6 = "Test Using Larger Than Block-Size Key - Hash Key First";
    check_hmac(key, 131, (const uint8_t *)t6, strlen(t6),
               "60e431591ee0b67f0d8a26aacbf5b77f8e0bc6213728c5140546040f0ee37f54", 32);
    /* Test case 7: key and data longer than a block */
    const char *t7 = "This is a test using a larger than block-size key and a larger than "
                     "block-size data. The key needs to be hashed before being used by the "
                     "HMAC algorithm.";
    check_hmac(key, 131, (const uint8_t *)t7, strlen(t7),
               "9b09ffa71b942fcb27635fbcd5b0e944bfdc63644f0713938a7f51535c3a35e2", 32);
}

static void constant_time_equal(void)
{
    uint8_t a[32], b[32];
    memset(a, 0x5a, sizeof a);
    memcpy(b, a, sizeof b);
    CHECK(exo_ct_equal(a, b, 32) == 1);
    CHECK(exo_ct_equal(a, b, 0) == 1);
    for (size_t i = 0; i < 32; i++)
        for (unsigned bit = 0; bit < 8; bit++) {
            b[i] = (uint8_t)(b[i] ^ (1u << bit));
            CHECK(exo_ct_equal(a, b, 32) == 0);
            b[i] = a[i];
        }
}

void test_crypto(void)
{
    sha256_vectors();
    rfc4231();
    constant_time_equal();
}
