/* timebase.c - TIM2 as a free-running microsecond counter (RM0410 "TIM2 to TIM5"). */
#include "timebase.h"

#include "clock.h"
#include "stm32f7_regs.h"

static uint32_t last;
static uint32_t high;

void timebase_init(void)
{
    RCC_APB1ENR |= RCC_APB1ENR_TIM2EN;
    (void)RCC_APB1ENR;
    TIM2_CR1 = 0u;
    /* APB1 is divided by 2, so the timer clock is 2 x 48 = 96 MHz. */
    TIM2_PSC = 2u * CLOCK_PCLK1_HZ / 1000000u - 1u;
    TIM2_ARR = 0xFFFFFFFFu;
    TIM2_EGR = 1u; /* UG: load the prescaler now */
    TIM2_CNT = 0u;
    last = 0u;
    high = 0u;
    TIM2_CR1 = 1u; /* CEN */
}

uint64_t timebase_now_us(void)
{
    uint32_t now = TIM2_CNT;
    if (now < last) {
        high++;
    }
    last = now;
    return (uint64_t)high << 32 | now;
}
