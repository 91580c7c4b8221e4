/*
 * console.h - text out on the CMSDK UART 0, which QEMU connects to its first serial
 * port (standard output with -nographic). Transmit only, polled.
 */
#ifndef CONSOLE_H
#define CONSOLE_H

#include <stdint.h>

void console_init(void);
void console_puts(const char *s);
void console_hex(const uint8_t *data, unsigned n);
void console_uint(uint32_t v);
void console_ipv4(uint32_t ip);

#endif /* CONSOLE_H */
