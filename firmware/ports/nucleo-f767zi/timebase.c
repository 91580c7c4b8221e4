/* timebase.c - TIM2 and TIM5 as free-running counters (RM0410 "TIM2 to TIM5"). */
#include "timebase.h"

#include "clock.h"
#include "stm32f7_regs.h"

/* APB1 is divided by 2, so the APB1 timers' clock is 2 x 48 = 96 MHz. */
#define TIMER_CLOCK_HZ (2u * CLOCK_PCLK1_HZ)
#define TIM5_PSC_VALUE (TIMER_CLOCK_HZ / 1000000u * TB_COARSE_TICK_US - 1u) /* 47999 */

static tb_ext ext;

/* Both counters are free running, up, over their full 32 bits; neither interrupts. */
void timebase_init(void)
{
    RCC_APB1ENR |= RCC_APB1ENR_TIM2EN | RCC_APB1ENR_TIM5EN;
    (void)RCC_APB1ENR;
    TIM2_CR1 = 0u;
    TIM5_CR1 = 0u;
    TIM2_PSC = TIMER_CLOCK_HZ / 1000000u - 1u;
    TIM5_PSC = TIM5_PSC_VALUE; /* fits the 16-bit prescaler */
    TIM2_ARR = 0xFFFFFFFFu;
    TIM5_ARR = 0xFFFFFFFFu;
    TIM2_EGR = 1u; /* UG: load the prescalers now */
    TIM5_EGR = 1u;
    TIM2_CNT = 0u;
    TIM5_CNT = 0u;
    TIM2_CR1 = 1u; /* CEN */
    TIM5_CR1 = 1u;
    tb_ext_init(&ext, TIM2_CNT, TIM5_CNT);
}

uint64_t timebase_now_us(void)
{
    uint32_t fine = TIM2_CNT;
    uint32_t coarse = TIM5_CNT;
    return tb_ext_update(&ext, fine, coarse);
}

const tb_ext *timebase_state(void)
{
    return &ext;
}
