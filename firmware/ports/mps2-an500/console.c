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

/* console_hex, console_uint, console_ipv4: console_format.c (both ports). */

