/*
 * fuzz_wire.c - libFuzzer harness for the core's wire decoder (exo_wire_decode).
 *
 * Built twice (firmware/fuzz/Makefile):
 * - wire_raw: the input is one datagram, as it came off the network.
 * - wire_auth (FZ_REAUTH): the first input byte is a control byte and the rest a
 *   datagram that the harness repairs after the fuzzer mutated it: bit 0 sets the header's
 *   length field to match the datagram (for its type byte), bit 1 the magic, and
 *   the tag is always recomputed with the test key, so mutations reach every check
 *   after `auth`.
 *
 * Either way the core's verdict must equal the independent model's
 * (fz_wire_model.c) and, for a valid packet, so must every field; the sanitizers
 * catch any read outside the datagram (it is copied into a buffer of exactly its
 * size).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fz_core_packet.h"
#include "fz_hmac.h"
#include "fz_wire_model.h"
#include "hmac.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The protocol document's test key: 00 01 02 ... 1f. */
static uint8_t KEY[32];
static exo_hmac_key CORE_KEY;
static int ready;

static void dump(const char *what, const uint8_t *d, size_t n)
{
    fprintf(stderr, "%s (%zu bytes):", what, n);
    for (size_t i = 0; i < n; i++)
        fprintf(stderr, " %02x", d[i]);
    fprintf(stderr, "\n");
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!ready) {
        for (unsigned i = 0; i < 32; i++)
            KEY[i] = (uint8_t)i;
        exo_hmac_set_key(&CORE_KEY, KEY, sizeof KEY);
        ready = 1;
    }
#ifdef FZ_REAUTH
    if (size < 1)
        return 0;
    unsigned control = data[0];
    data++;
    size--;
#endif
    if (size > 4096)
        return 0;
    uint8_t *d = malloc(size ? size : 1u); /* exact size: ASan sees any overread */
    if (!d)
        abort();
    if (size)
        memcpy(d, data, size);
#ifdef FZ_REAUTH
    if (size >= 44) {
        if (control & 2u) {
            d[0] = 0x45;
            d[1] = 0x58;
        }
        if (control & 1u) {
            size_t payload = size - 8 - (d[3] == FZ_T_VERSION ? 32u : 48u);
            if (size >= 8 + 48 || d[3] == FZ_T_VERSION) {
                d[4] = (uint8_t)payload;
                d[5] = (uint8_t)(payload >> 8);
            }
        }
        fz_reauth(KEY, d, size);
    }
#endif
    fz_pkt model, core, again;
    fz_reason want = fz_wire_check(KEY, d, size, &model);
    const char *got = fz_core_decode(&CORE_KEY, d, size, &core);
    const char *got2 = fz_core_decode(&CORE_KEY, d, size, &again);
    if (strcmp(got, got2) != 0 || memcmp(&core, &again, sizeof core) != 0) {
        dump("datagram", d, size);
        fprintf(stderr, "core decoder is not deterministic: %s then %s\n", got, got2);
        abort();
    }
#ifdef FZ_TOLERATE_SAMPLE_ORDER
    /* A disagreement the harness found once (fixed in the core since): a SAMPLE's
     * counts and status checked before its payload size. Tolerated only when built on
     * purpose (make FZ_TOLERATE=1), to look past it in an older core. */
    if (want == FZ_LENGTH && size > 3 && d[3] == FZ_T_SAMPLE &&
        (strcmp(got, "counts") == 0 || strcmp(got, "status") == 0))
        got = "length";
#endif
    if (strcmp(got, fz_reason_name(want)) != 0) {
        dump("datagram", d, size);
        fprintf(stderr, "verdict: core %s, document (model) %s\n", got, fz_reason_name(want));
        abort();
    }
    if (want == FZ_OK) {
        int line = fz_pkt_diff(&core, &model);
        if (line) {
            dump("datagram", d, size);
            fprintf(stderr, "valid packet decoded differently (fz_core_packet.c line %d)\n", line);
            abort();
        }
    }
    free(d);
    return 0;
}
