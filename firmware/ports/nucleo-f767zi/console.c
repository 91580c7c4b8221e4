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

/* console_hex, console_uint, console_ipv4: console_format.c (both ports). */

