/* console.c - USART3 transmit only (RM0410 "Universal synchronous/asynchronous
 * receiver transmitter"). */
#include "console.h"

#include "clock.h"
#include "gpio.h"

#define USART3_BASE 0x40004800u
#define USART3_CR1 REG32(USART3_BASE + 0x00u)
#define USART3_BRR REG32(USART3_BASE + 0x0Cu)
#define USART3_ISR REG32(USART3_BASE + 0x1Cu)
#define USART3_TDR REG32(USART3_BASE + 0x28u)
#define USART_CR1_UE (1u << 0)
#define USART_CR1_TE (1u << 3)
#define USART_ISR_TXE (1u << 7)
#define RCC_APB1ENR_USART3EN (1u << 18)
#define AF_USART3 7u
#define BAUD 115200u
#define CHAR_TIMEOUT_CYCLES (CLOCK_HCLK_HZ / 1000u)

static int ready;

void console_init(uint32_t pclk1_hz)
{
    gpio_alternate((pin_t){PORT_D, 8u}, AF_USART3, 0);
    RCC_APB1ENR |= RCC_APB1ENR_USART3EN;
    (void)RCC_APB1ENR;
    USART3_CR1 = 0u;
    USART3_BRR = (pclk1_hz + BAUD / 2u) / BAUD; /* 16x oversampling */
    USART3_CR1 = USART_CR1_TE | USART_CR1_UE;
    ready = 1;
}

static void put(char c)
{
    uint32_t start = DWT_CYCCNT;
    while (!(USART3_ISR & USART_ISR_TXE)) {
        if (DWT_CYCCNT - start > CHAR_TIMEOUT_CYCLES) {
            return; /* never hang on the console */
        }
    }
    USART3_TDR = (uint8_t)c;
}

void console_puts(const char *s)
{
    if (!ready) {
        return;
    }
    for (; *s; s++) {
        if (*s == '\n') {
            put('\r');
        }
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
