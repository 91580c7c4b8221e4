/* sbc_key.c - the link key file. */
#include "sbc_key.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static int hex_value(char c)
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

static int is_space(char c)
{
    return c == ' ' || c == '\t' || c == '\n' || c == '\r';
}

int sbc_key_parse(const char *text, size_t len, uint8_t key[SBC_KEY_BYTES], char *err,
                  size_t errlen)
{
    size_t a = 0, b = len;
    while (a < b && is_space(text[a])) {
        a++;
    }
    while (b > a && is_space(text[b - 1])) {
        b--;
    }
    if (b - a != 2 * SBC_KEY_BYTES) {
        snprintf(err, errlen, "the key must be %d hex digits, found %zu characters",
                 2 * SBC_KEY_BYTES, b - a);
        return -1;
    }
    for (size_t i = 0; i < SBC_KEY_BYTES; i++) {
        int hi = hex_value(text[a + 2 * i]), lo = hex_value(text[a + 2 * i + 1]);
        if (hi < 0 || lo < 0) {
            snprintf(err, errlen, "not hexadecimal at character %zu", 2 * i + (hi < 0 ? 1 : 2));
            return -1;
        }
        key[i] = (uint8_t)(hi << 4 | lo);
    }
    return 0;
}

int sbc_key_load(const char *path, uint8_t key[SBC_KEY_BYTES], char *err, size_t errlen)
{
    char text[256];
    char why[128];
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        return -1;
    }
    struct stat st;
    if (fstat(fd, &st) != 0) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        close(fd);
        return -1;
    }
    if ((st.st_mode & (S_IRWXG | S_IRWXO)) != 0) {
        snprintf(err, errlen, "%s: readable by others (mode %o); chmod 600 it", path,
                 (unsigned)(st.st_mode & 07777));
        close(fd);
        return -1;
    }
    ssize_t n = read(fd, text, sizeof text);
    close(fd);
    if (n < 0) {
        snprintf(err, errlen, "%s: %s", path, strerror(errno));
        return -1;
    }
    int rc = sbc_key_parse(text, (size_t)n, key, why, sizeof why);
    memset(text, 0, sizeof text);
    if (rc != 0) {
        snprintf(err, errlen, "%s: %s", path, why);
    }
    return rc;
}
