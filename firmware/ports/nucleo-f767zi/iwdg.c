/* iwdg.c - IWDG registers (RM0410 "Independent watchdog"); timing in iwdg_timing.h. */
#include "iwdg.h"

#include "iwdg_timing.h"
#include "stm32f7_regs.h"

/* Compile-time checks of the worst cases (C99 has no static_assert: a negative array
 * size fails the build). Slowest LSI: 446 * 4 / 17 kHz = 104.9 ms <= 110 ms. Fastest:
 * 446 * 4 / 47 kHz = 37.9 ms, at least three kick periods. */
typedef char iwdg_slowest_within_110ms[(IWDG_RELOAD + 1u) * IWDG_DIVIDER * 1000u <=
                                               IWDG_RELEASE_MAX_US / 1000u * IWDG_LSI_MIN_HZ
                                           ? 1
                                           : -1];
typedef char iwdg_fastest_three_kicks[(IWDG_RELOAD + 1u) * IWDG_DIVIDER * 1000u >=
                                              3u * IWDG_KICK_PERIOD_US / 1000u * IWDG_LSI_MAX_HZ
                                          ? 1
                                          : -1];
typedef char iwdg_reload_fits[IWDG_RELOAD <= 0xFFFu ? 1 : -1];

void iwdg_start(void)
{
    IWDG_KR = IWDG_KEY_START; /* also starts the LSI */
    IWDG_KR = IWDG_KEY_UNLOCK;
    IWDG_PR = IWDG_PR_VALUE;
    IWDG_RLR = IWDG_RELOAD;
    while (IWDG_SR & 3u) { /* PVU, RVU: the new values reach the LSI domain */
    }
    IWDG_KR = IWDG_KEY_RELOAD;
}

void iwdg_kick(void)
{
    IWDG_KR = IWDG_KEY_RELOAD;
}

int iwdg_caused_reset(void)
{
    int was = (RCC_CSR & RCC_CSR_IWDGRSTF) != 0u;
    RCC_CSR |= RCC_CSR_RMVF;
    return was;
}
