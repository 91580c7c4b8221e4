/*
 * hmac.c - HMAC-SHA256, RFC 2104: H((K ^ opad) || H((K ^ ipad) || message)).
 */
#include "hmac.h"

#include <string.h>

void exo_hmac_set_key(exo_hmac_key *k, const uint8_t *key, size_t key_len)
{
    uint8_t block[EXO_SHA256_BLOCK];
    memset(block, 0, sizeof block);
    if (key_len > EXO_SHA256_BLOCK)
        exo_sha256(key, key_len, block); /* RFC 2104 section 2: hash over-long keys */
    else if (key_len > 0)
        memcpy(block, key, key_len);

    uint8_t pad[EXO_SHA256_BLOCK];
    for (size_t i = 0; i < sizeof pad; i++)
        pad[i] = (uint8_t)(block[i] ^ 0x36u);
    exo_sha256_init(&k->inner);
    exo_sha256_update(&k->inner, pad, sizeof pad);
    for (size_t i = 0; i < sizeof pad; i++)
        pad[i] = (uint8_t)(block[i] ^ 0x5cu);
    exo_sha256_init(&k->outer);
    exo_sha256_update(&k->outer, pad, sizeof pad);
    exo_secure_zero(block, sizeof block);
    exo_secure_zero(pad, sizeof pad);
}

void exo_hmac_sha256(const exo_hmac_key *k, const uint8_t *a, size_t a_len, const uint8_t *b,
                     size_t b_len, uint8_t out[EXO_SHA256_BYTES])
{
    uint8_t inner_digest[EXO_SHA256_BYTES];
    exo_sha256_ctx c = k->inner; /* copy: the precomputed state is reused for every tag */
    exo_sha256_update(&c, a, a_len);
    if (b_len > 0)
        exo_sha256_update(&c, b, b_len);
    exo_sha256_final(&c, inner_digest);
    c = k->outer;
    exo_sha256_update(&c, inner_digest, sizeof inner_digest);
    exo_sha256_final(&c, out);
    /* The state copied from the absorbed key is as good as the key for forging tags. */
    exo_secure_zero(&c, sizeof c);
    exo_secure_zero(inner_digest, sizeof inner_digest);
}

int exo_ct_equal(const uint8_t *a, const uint8_t *b, size_t n)
{
    /* Accumulate every difference; one branch at the end, on the total only. The
     * volatile keeps the compiler from turning the loop into an early-exit memcmp. */
    volatile uint8_t diff = 0;
    for (size_t i = 0; i < n; i++)
        diff = (uint8_t)(diff | (a[i] ^ b[i]));
    return diff == 0;
}

void exo_secure_zero(void *p, size_t n)
{
    volatile uint8_t *v = (volatile uint8_t *)p;
    for (size_t i = 0; i < n; i++)
        v[i] = 0;
}
