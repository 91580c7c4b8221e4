/* timebase.c - CMSDK APB timer 0 extended to 64 bits of 25 MHz ticks. */
#include "timebase.h"

#include "mps2_regs.h"

#define TICKS_PER_US (MPS2_SYSCLK_HZ / 1000000u)

static uint32_t last;
static uint64_t ticks;

void timebase_init(void)
{
    TIMER_CTRL(TIMER0_BASE) = 0u;
    TIMER_RELOAD(TIMER0_BASE) = 0xFFFFFFFFu;
    TIMER_VALUE(TIMER0_BASE) = 0xFFFFFFFFu;
    TIMER_CTRL(TIMER0_BASE) = TIMER_CTRL_EN; /* no interrupt */
    last = TIMER_VALUE(TIMER0_BASE);
    ticks = 0u;
}

uint32_t timebase_raw(void)
{
    return TIMER_VALUE(TIMER0_BASE);
}

uint64_t timebase_now_us(void)
{
    uint32_t now = TIMER_VALUE(TIMER0_BASE);
    ticks += (uint32_t)(last - now); /* counts down; unsigned difference spans a wrap */
    last = now;
    return ticks / TICKS_PER_US;
}
