/*
 * console.h - boot messages on USART3 (PD8 TX), which the Nucleo-144 routes to the
 * ST-LINK's virtual COM port: 115200 baud, 8N1 (`screen /dev/ttyACM0 115200`).
 *
 * Writes block (about 87 us per character), so they are used at start-up and on the
 * fault path only, never in the sample loop.
 */
#ifndef CONSOLE_H
#define CONSOLE_H

#include <stdint.h>

/* `pclk1_hz`: the APB1 clock the baud rate is derived from (lower if the PLL failed). */
void console_init(uint32_t pclk1_hz);
void console_puts(const char *s);
void console_hex(const uint8_t *data, unsigned n);
void console_ipv4(uint32_t ip);
void console_uint(uint32_t v);

#endif /* CONSOLE_H */
