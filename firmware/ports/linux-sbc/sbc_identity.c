/* sbc_identity.c - unique id, firmware name and key id of exo-sbc (sbc_identity.h). */
#include "sbc_identity.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "hmac.h"

static int hex_digit(char c)
{
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    if (c >= 'a' && c <= 'f') {
        return c - 'a' + 10;
    }
    if (c >= 'A' && c <= 'F') {
        return c - 'A' + 10;
    }
    return -1;
}

int sbc_parse_device_id(const char *hex, uint8_t out[SBC_UNIQUE_ID_BYTES])
{
    size_t n = strlen(hex);
    if (n == 0u || n > 2u * SBC_UNIQUE_ID_BYTES) {
        return -1;
    }
    uint8_t id[SBC_UNIQUE_ID_BYTES];
    memset(id, 0, sizeof id);
    /* With an odd count the first digit stands alone (a leading 0 is implied). */
    size_t digit = n % 2u;
    for (size_t i = 0; i < n; i++, digit++) {
        int v = hex_digit(hex[i]);
        if (v < 0) {
            return -1;
        }
        id[digit / 2u] = (uint8_t)(id[digit / 2u] | (digit % 2u ? v : v << 4));
    }
    memcpy(out, id, sizeof id);
    return 0;
}

int sbc_parse_machine_id(const char *text, size_t len, uint8_t out[SBC_UNIQUE_ID_BYTES])
{
    while (len > 0u && (text[len - 1u] == '\n' || text[len - 1u] == '\r')) {
        len--;
    }
    if (len != 2u * SBC_UNIQUE_ID_BYTES) {
        return -1;
    }
    char digits[2u * SBC_UNIQUE_ID_BYTES + 1u];
    memcpy(digits, text, len);
    digits[len] = '\0';
    uint8_t id[SBC_UNIQUE_ID_BYTES];
    if (sbc_parse_device_id(digits, id) != 0) {
        return -1;
    }
    static const uint8_t zero[SBC_UNIQUE_ID_BYTES];
    if (memcmp(id, zero, sizeof id) == 0) {
        return -1; /* an uninitialised machine-id is not an identity */
    }
    memcpy(out, id, sizeof id);
    return 0;
}

void sbc_unique_id_from_machine_id(const uint8_t machine_id[SBC_UNIQUE_ID_BYTES],
                                   uint8_t out[SBC_UNIQUE_ID_BYTES])
{
    static const uint8_t label[] = "exo-sbc unique id";
    exo_hmac_key k;
    uint8_t tag[EXO_SHA256_BYTES];
    exo_hmac_set_key(&k, machine_id, SBC_UNIQUE_ID_BYTES);
    exo_hmac_sha256(&k, label, sizeof label - 1u, NULL, 0u, tag);
    memcpy(out, tag, SBC_UNIQUE_ID_BYTES);
    exo_secure_zero(&k, sizeof k);
    exo_secure_zero(tag, sizeof tag);
}

int sbc_unique_id_load(const char *path, uint8_t out[SBC_UNIQUE_ID_BYTES], char *err,
                       size_t errlen)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        snprintf(err, errlen, "%s: %s (give the board a serial number with --device-id HEX)",
                 path, strerror(errno));
        return -1;
    }
    char text[80];
    ssize_t n = read(fd, text, sizeof text);
    close(fd);
    uint8_t machine_id[SBC_UNIQUE_ID_BYTES];
    if (n < 0 || sbc_parse_machine_id(text, (size_t)n, machine_id) != 0) {
        snprintf(err, errlen, "%s: not 32 hexadecimal digits (give the board a serial number "
                              "with --device-id HEX)", path);
        return -1;
    }
    sbc_unique_id_from_machine_id(machine_id, out);
    exo_secure_zero(machine_id, sizeof machine_id);
    return 0;
}

void sbc_key_id(const uint8_t *key, size_t key_len, char out[SBC_KEY_ID_HEX + 1])
{
    static const uint8_t label[] = "exostudy key id";
    static const char digits[] = "0123456789abcdef";
    exo_hmac_key k;
    uint8_t tag[EXO_SHA256_BYTES];
    exo_hmac_set_key(&k, key, key_len);
    exo_hmac_sha256(&k, label, sizeof label - 1u, NULL, 0u, tag);
    exo_secure_zero(&k, sizeof k);
    for (unsigned i = 0; i < SBC_KEY_ID_HEX / 2u; i++) {
        out[2u * i] = digits[tag[i] >> 4];
        out[2u * i + 1u] = digits[tag[i] & 15u];
    }
    out[SBC_KEY_ID_HEX] = '\0';
}
