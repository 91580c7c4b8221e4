/*
 * main.c - runs every suite and prints the closing line, nothing else on success.
 */
#include <stdio.h>
#include <string.h>

#include "check.h"

unsigned long check_passed, check_failed;

void check_report(int ok, const char *file, int line, const char *what)
{
    if (ok) {
        check_passed++;
        return;
    }
    check_failed++;
    fprintf(stderr, "%s:%d: failed: %s\n", file, line, what);
}

void check_report_u(int ok, const char *file, int line, const char *what, unsigned long long got,
                    unsigned long long want)
{
    check_report(ok, file, line, what);
    if (!ok)
        fprintf(stderr, "    got %llu (0x%llx), want %llu (0x%llx)\n", got, got, want, want);
}

void check_report_bytes(int ok, const char *file, int line, const char *what, const uint8_t *got,
                        const uint8_t *want, size_t n)
{
    check_report(ok, file, line, what);
    if (ok)
        return;
    for (size_t i = 0; i < n; i++)
        if (got[i] != want[i]) {
            fprintf(stderr, "    first difference at byte %zu: got %02x, want %02x\n", i, got[i],
                    want[i]);
            break;
        }
}

static int hex_value(char c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

size_t hex_bytes(const char *hex, uint8_t *out, size_t cap)
{
    size_t n = 0;
    int high = -1;
    for (; *hex; hex++) {
        int v = hex_value(*hex);
        if (v < 0)
            continue;
        if (high < 0) {
            high = v;
        } else {
            if (n < cap)
                out[n] = (uint8_t)(high << 4 | v);
            n++;
            high = -1;
        }
    }
    return n;
}

int main(void)
{
    test_crypto();
    test_wire();
    test_session();
    test_watchdog();
    test_as5048a();
    test_device();
    printf("%lu passed, %lu failed\n", check_passed, check_failed);
    return check_failed == 0 ? 0 : 1;
}
