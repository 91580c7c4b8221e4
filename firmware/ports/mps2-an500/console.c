/* console.c - the CMSDK APB UART, transmit only. */
#include "console.h"

#include "mps2_regs.h"

#define BAUD 115200u
#define CHAR_SPIN_LIMIT 100000u

static int ready;

void console_init(void)
{
    UART_BAUDDIV(UART0_BASE) = MPS2_SYSCLK_HZ / BAUD; /* at least 16, as the UART needs */
    UART_CTRL(UART0_BASE) = UART_CTRL_TXEN;
    ready = 1;
}

static void put(char c)
{
    for (uint32_t i = 0; (UART_STATE(UART0_BASE) & UART_STATE_TXFULL) != 0u; i++) {
        if (i == CHAR_SPIN_LIMIT) {
            return; /* never hang on the console */
        }
    }
    UART_DATA(UART0_BASE) = (uint8_t)c;
}

void console_puts(const char *s)
{
    if (!ready) {
        return;
    }
    for (; *s; s++) {
        put(*s);
    }
}

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
