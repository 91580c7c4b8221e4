/* clock.c - PLL set-up (RM0410 "Reset and clock control"). */
#include "clock.h"

#include "stm32f7_regs.h"

#define WAIT_LOOPS 2000000u /* a few tens of ms at 16 MHz: far beyond any start-up time */

static int wait_set(volatile uint32_t *reg, uint32_t bit)
{
    for (uint32_t i = 0; i < WAIT_LOOPS; i++) {
        if (*reg & bit) {
            return 0;
        }
    }
    return -1;
}

static void dwt_init(void)
{
    DEMCR |= DEMCR_TRCENA;
    DWT_LAR = 0xC5ACCE55u;
    DWT_CYCCNT = 0u;
    DWT_CTRL |= 1u; /* CYCCNTENA */
}

void clock_delay_cycles(uint32_t cycles)
{
    uint32_t start = DWT_CYCCNT;
    while (DWT_CYCCNT - start < cycles) {
    }
}

static void icache_enable(void)
{
    __asm__ volatile("dsb\n isb" ::: "memory");
    SCB_ICIALLU = 0u;
    __asm__ volatile("dsb\n isb" ::: "memory");
    SCB_CCR |= SCB_CCR_IC;
    __asm__ volatile("dsb\n isb" ::: "memory");
}

clock_source clock_init(void)
{
    clock_source src = CLOCK_FROM_HSE;
    uint32_t pllm = 4u; /* 8 MHz / 4 = 2 MHz PLL input (1..2 MHz allowed) */

    RCC_APB1ENR |= RCC_APB1ENR_PWREN; /* regulator stays at its reset scale 1 */
    (void)RCC_APB1ENR;

    RCC_CR |= RCC_CR_HSEBYP | RCC_CR_HSEON;
    if (wait_set(&RCC_CR, RCC_CR_HSERDY) != 0) {
        RCC_CR &= ~(RCC_CR_HSEON | RCC_CR_HSEBYP);
        src = CLOCK_FROM_HSI;
        pllm = 8u; /* 16 MHz / 8 = 2 MHz */
    }

    /* VCO = 2 MHz x 192 = 384 MHz; SYSCLK = VCO / 4 = 96 MHz; 48 MHz = VCO / 8. */
    RCC_CR &= ~RCC_CR_PLLON;
    RCC_PLLCFGR = pllm | (192u << 6) | (1u << 16) /* P = 4 */ | (8u << 24) /* Q = 8 */ |
                  (2u << 28) /* R = 2, its reset value (DSI only) */ |
                  (src == CLOCK_FROM_HSE ? RCC_PLLCFGR_SRC_HSE : 0u);
    RCC_CR |= RCC_CR_PLLON;
    if (wait_set(&RCC_CR, RCC_CR_PLLRDY) != 0) {
        dwt_init();
        return CLOCK_FAILED; /* stay on the 16 MHz HSI */
    }

    /* 3 wait states for 90 < HCLK <= 120 MHz at 2.7..3.6 V, before speeding up. */
    FLASH_ACR = (FLASH_ACR & ~0xFu) | 3u | FLASH_ACR_PRFTEN;
    while ((FLASH_ACR & 0xFu) != 3u) {
    }

    /* AHB /1, APB1 /2 (PPRE1 = 100), APB2 /1, then switch to the PLL. */
    RCC_CFGR = (RCC_CFGR & ~((0xFu << 4) | (7u << 10) | (7u << 13))) | (4u << 10);
    RCC_CFGR = (RCC_CFGR & ~3u) | 2u;
    while (((RCC_CFGR >> 2) & 3u) != 2u) {
    }
    RCC_DCKCFGR2 &= ~RCC_DCKCFGR2_CK48MSEL;

    dwt_init();
    icache_enable(); /* data cache stays off: Ethernet DMA buffers need no maintenance */
    return src;
}
