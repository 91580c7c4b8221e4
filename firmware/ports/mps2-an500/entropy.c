/* entropy.c - the emulation-only generator (entropy.h). */
#include "entropy.h"

#include "hmac.h"
#include "timebase.h"

static exo_hmac_key key;
static uint64_t counter;
static int seeded;

void entropy_init(const uint8_t seed[32])
{
    exo_hmac_set_key(&key, seed, 32u);
    counter = 0u;
    seeded = 1;
}

int entropy_read(void *ctx, uint8_t *out, size_t n)
{
    (void)ctx;
    if (!seeded) {
        return -1;
    }
    while (n > 0u) {
        uint8_t msg[12];
        uint32_t t = timebase_raw();
        for (unsigned i = 0; i < 8u; i++) {
            msg[i] = (uint8_t)(counter >> (8u * i));
        }
        for (unsigned i = 0; i < 4u; i++) {
            msg[8u + i] = (uint8_t)(t >> (8u * i));
        }
        counter++;
        uint8_t block[EXO_SHA256_BYTES];
        exo_hmac_sha256(&key, msg, sizeof msg, 0, 0u, block);
        size_t take = n < sizeof block ? n : sizeof block;
        for (size_t i = 0; i < take; i++) {
            out[i] = block[i];
        }
        out += take;
        n -= take;
    }
    return 0;
}
