/* iwdg.c - IWDG registers (RM0410 "Independent watchdog"). */
#include "iwdg.h"

#include "stm32f7_regs.h"

#define IWDG_PR_DIV8 1u
#define IWDG_RELOAD 400u

void iwdg_start(void)
{
    IWDG_KR = IWDG_KEY_START; /* also starts the LSI */
    IWDG_KR = IWDG_KEY_UNLOCK;
    IWDG_PR = IWDG_PR_DIV8;
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
