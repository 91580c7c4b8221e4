/*
 * console_format.c - numbers, bytes and addresses written through the port's
 * console_puts; shared by the Nucleo-F767ZI and the emulated mps2-an500 ports, which
 * differ only in the UART underneath.
 */
#include "console.h"

void console_hex(const uint8_t *data, unsigned n)
{
    static const char digits[] = "0123456789abcdef";
    char buf[3] = {0, 0, 0};
    for (unsigned i = 0; i < n; i++) {
        buf[0] = digits[data[i] >> 4];
        buf[1] = digits[data[i] & 15u];
        console_puts(buf);
    }
}

void console_uint(uint32_t v)
{
    char buf[11];
    int i = 10;
    buf[i] = '\0';
    do {
        buf[--i] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v != 0u);
    console_puts(&buf[i]);
}

void console_ipv4(uint32_t ip)
{
    for (int shift = 24; shift >= 0; shift -= 8) {
        console_uint((ip >> shift) & 255u);
        if (shift != 0) {
            console_puts(".");
        }
    }
}
