/*
 * stm32f7_regs.h - the STM32F76x/77x registers this port uses, by address.
 *
 * No vendor headers are used (none is installable here); every address, offset and
 * bit below was written from ST's reference manual RM0410 (STM32F76xxx/77xxx) and,
 * for the core registers, ARM's Cortex-M7 documentation. Only what the port touches
 * is listed, named as in the manual.
 */
#ifndef STM32F7_REGS_H
#define STM32F7_REGS_H

#include <stdint.h>

#define REG32(addr) (*(volatile uint32_t *)(uintptr_t)(addr))
#define REG16(addr) (*(volatile uint16_t *)(uintptr_t)(addr))

/* ---- Cortex-M7 system control (ARMv7-M) ---- */
#define SCB_CPACR REG32(0xE000ED88u)   /* coprocessor access: CP10/CP11 = FPU */
#define SCB_AIRCR REG32(0xE000ED0Cu)
#define SCB_AIRCR_RESET 0x05FA0004u    /* VECTKEY | SYSRESETREQ */
#define SCB_VTOR REG32(0xE000ED08u)
#define SCB_CCR REG32(0xE000ED14u)
#define SCB_CCR_IC (1u << 17)          /* instruction cache enable */
#define SCB_ICIALLU REG32(0xE000EF50u) /* invalidate the whole I-cache */
#define DEMCR REG32(0xE000EDFCu)
#define DEMCR_TRCENA (1u << 24)
#define DWT_CTRL REG32(0xE0001000u)
#define DWT_CYCCNT REG32(0xE0001004u)
#define DWT_LAR REG32(0xE0001FB0u)     /* lock access: 0xC5ACCE55 unlocks on the M7 */

/* ---- Memory map ---- */
#define PERIPH_APB1 0x40000000u
#define PERIPH_APB2 0x40010000u
#define PERIPH_AHB1 0x40020000u
#define PERIPH_AHB2 0x50000000u
#define UID_BASE 0x1FF0F420u           /* 96-bit unique device ID (RM0410 "Unique device ID register") */

/* ---- RCC (0x40023800) ---- */
#define RCC_BASE 0x40023800u
#define RCC_CR REG32(RCC_BASE + 0x00u)
#define RCC_CR_HSION (1u << 0)
#define RCC_CR_HSIRDY (1u << 1)
#define RCC_CR_HSEON (1u << 16)
#define RCC_CR_HSERDY (1u << 17)
#define RCC_CR_HSEBYP (1u << 18)
#define RCC_CR_PLLON (1u << 24)
#define RCC_CR_PLLRDY (1u << 25)
#define RCC_PLLCFGR REG32(RCC_BASE + 0x04u) /* M[5:0] N[14:6] P[17:16] SRC[22] Q[27:24] */
#define RCC_PLLCFGR_SRC_HSE (1u << 22)
#define RCC_CFGR REG32(RCC_BASE + 0x08u)    /* SW[1:0] SWS[3:2] HPRE[7:4] PPRE1[12:10] PPRE2[15:13] */
#define RCC_AHB1RSTR REG32(RCC_BASE + 0x10u)
#define RCC_AHB1RSTR_ETHMACRST (1u << 25)
#define RCC_AHB1ENR REG32(RCC_BASE + 0x30u)
#define RCC_AHB1ENR_GPIOAEN (1u << 0)       /* GPIOxEN = bit x (A=0 .. G=6) */
#define RCC_AHB1ENR_ETHMACEN (1u << 25)
#define RCC_AHB1ENR_ETHMACTXEN (1u << 26)
#define RCC_AHB1ENR_ETHMACRXEN (1u << 27)
#define RCC_AHB2ENR REG32(RCC_BASE + 0x34u)
#define RCC_AHB2ENR_RNGEN (1u << 6)
#define RCC_APB1ENR REG32(RCC_BASE + 0x40u)
#define RCC_APB1ENR_TIM2EN (1u << 0)
#define RCC_APB1ENR_TIM5EN (1u << 3)
#define RCC_APB1ENR_PWREN (1u << 28)
#define RCC_APB2ENR REG32(RCC_BASE + 0x44u)
#define RCC_APB2ENR_SPI1EN (1u << 12)
#define RCC_APB2ENR_SYSCFGEN (1u << 14)
#define RCC_CSR REG32(RCC_BASE + 0x74u)
#define RCC_CSR_IWDGRSTF (1u << 29)         /* last reset was the independent watchdog */
#define RCC_CSR_RMVF (1u << 24)             /* clear the reset flags */
#define RCC_DCKCFGR2 REG32(RCC_BASE + 0x90u)
#define RCC_DCKCFGR2_CK48MSEL (1u << 27)    /* 0: 48 MHz clock from the main PLL's Q */

/* ---- Flash interface (0x40023C00) ---- */
#define FLASH_ACR REG32(0x40023C00u)         /* LATENCY[3:0] PRFTEN[8] ARTEN[9] */
#define FLASH_ACR_PRFTEN (1u << 8)

/* ---- GPIO ports (AHB1, 0x400 apart) ---- */
#define GPIO_BASE(port) (PERIPH_AHB1 + 0x400u * (uint32_t)(port)) /* port 0 = A */
#define GPIO_MODER(p) REG32(GPIO_BASE(p) + 0x00u)
#define GPIO_OTYPER(p) REG32(GPIO_BASE(p) + 0x04u)
#define GPIO_OSPEEDR(p) REG32(GPIO_BASE(p) + 0x08u)
#define GPIO_PUPDR(p) REG32(GPIO_BASE(p) + 0x0Cu)
#define GPIO_IDR(p) REG32(GPIO_BASE(p) + 0x10u)
#define GPIO_ODR(p) REG32(GPIO_BASE(p) + 0x14u)
#define GPIO_BSRR(p) REG32(GPIO_BASE(p) + 0x18u) /* low half sets, high half resets */
#define GPIO_AFRL(p) REG32(GPIO_BASE(p) + 0x20u)
#define GPIO_AFRH(p) REG32(GPIO_BASE(p) + 0x24u)
#define PORT_A 0u
#define PORT_B 1u
#define PORT_C 2u
#define PORT_D 3u
#define PORT_E 4u
#define PORT_F 5u
#define PORT_G 6u

/* ---- SYSCFG (0x40013800) ---- */
#define SYSCFG_PMC REG32(0x40013804u)
#define SYSCFG_PMC_MII_RMII_SEL (1u << 23)

/* ---- TIM2: 32-bit general-purpose timer (APB1, 0x40000000) ---- */
#define TIM2_CR1 REG32(0x40000000u)
#define TIM2_EGR REG32(0x40000014u)
#define TIM2_CNT REG32(0x40000024u)
#define TIM2_PSC REG32(0x40000028u)
#define TIM2_ARR REG32(0x4000002Cu)

/* ---- TIM5: the other 32-bit general-purpose timer (APB1, 0x40000C00) ---- */
#define TIM5_CR1 REG32(0x40000C00u)
#define TIM5_EGR REG32(0x40000C14u)
#define TIM5_CNT REG32(0x40000C24u)
#define TIM5_PSC REG32(0x40000C28u)
#define TIM5_ARR REG32(0x40000C2Cu)

/* ---- IWDG (0x40003000) ---- */
#define IWDG_KR REG32(0x40003000u)
#define IWDG_PR REG32(0x40003004u)
#define IWDG_RLR REG32(0x40003008u)
#define IWDG_SR REG32(0x4000300Cu)
#define IWDG_KEY_START 0xCCCCu
#define IWDG_KEY_RELOAD 0xAAAAu
#define IWDG_KEY_UNLOCK 0x5555u

/* ---- SPI1 (APB2, 0x40013000), the F7's SPI with data size field ---- */
#define SPI1_CR1 REG32(0x40013000u)
#define SPI_CR1_CPHA (1u << 0)
#define SPI_CR1_CPOL (1u << 1)
#define SPI_CR1_MSTR (1u << 2)
#define SPI_CR1_BR_SHIFT 3u                 /* f_PCLK / 2^(BR+1) */
#define SPI_CR1_SPE (1u << 6)
#define SPI_CR1_SSI (1u << 8)
#define SPI_CR1_SSM (1u << 9)
#define SPI1_CR2 REG32(0x40013004u)
#define SPI_CR2_DS_16BIT (0xFu << 8)
#define SPI1_SR REG32(0x40013008u)
#define SPI_SR_RXNE (1u << 0)
#define SPI_SR_TXE (1u << 1)
#define SPI_SR_MODF (1u << 5)
#define SPI_SR_OVR (1u << 6)
#define SPI_SR_BSY (1u << 7)
#define SPI1_DR16 REG16(0x4001300Cu)        /* 16-bit access: one frame */

/* ---- RNG (AHB2, 0x50060800) ---- */
#define RNG_CR REG32(0x50060800u)
#define RNG_CR_RNGEN (1u << 2)
#define RNG_SR REG32(0x50060804u)
#define RNG_SR_DRDY (1u << 0)
#define RNG_SR_CECS (1u << 1)
#define RNG_SR_SECS (1u << 2)
#define RNG_SR_CEIS (1u << 5)
#define RNG_SR_SEIS (1u << 6)
#define RNG_DR REG32(0x50060808u)

/* ---- Ethernet MAC (0x40028000) and its DMA (0x40029000) ---- */
#define ETH_BASE 0x40028000u
#define ETH_MACCR REG32(ETH_BASE + 0x00u)
#define ETH_MACCR_RE (1u << 2)
#define ETH_MACCR_TE (1u << 3)
#define ETH_MACCR_DM (1u << 11)             /* full duplex */
#define ETH_MACCR_FES (1u << 14)            /* 100 Mbit/s */
#define ETH_MACCR_CSTF (1u << 25)           /* strip the FCS of type frames */
#define ETH_MACFFR REG32(ETH_BASE + 0x04u)
#define ETH_MACMIIAR REG32(ETH_BASE + 0x10u)
#define ETH_MACMIIAR_MB (1u << 0)           /* busy */
#define ETH_MACMIIAR_MW (1u << 1)           /* write */
#define ETH_MACMIIAR_CR_SHIFT 2u            /* MDC clock range */
#define ETH_MACMIIAR_MR_SHIFT 6u            /* PHY register */
#define ETH_MACMIIAR_PA_SHIFT 11u           /* PHY address */
#define ETH_MACMIIDR REG32(ETH_BASE + 0x14u)
#define ETH_MACA0HR REG32(ETH_BASE + 0x40u)
#define ETH_MACA0LR REG32(ETH_BASE + 0x44u)
#define ETH_MMCRIMR REG32(ETH_BASE + 0x10Cu) /* MMC receive interrupt mask */
#define ETH_MMCTIMR REG32(ETH_BASE + 0x110u) /* MMC transmit interrupt mask */
#define ETH_DMABMR REG32(ETH_BASE + 0x1000u)
#define ETH_DMABMR_SR (1u << 0)             /* software reset */
#define ETH_DMABMR_PBL_SHIFT 8u
#define ETH_DMABMR_FB (1u << 16)
#define ETH_DMABMR_RDP_SHIFT 17u
#define ETH_DMABMR_USP (1u << 23)
#define ETH_DMABMR_AAB (1u << 25)
#define ETH_DMATPDR REG32(ETH_BASE + 0x1004u)
#define ETH_DMARPDR REG32(ETH_BASE + 0x1008u)
#define ETH_DMARDLAR REG32(ETH_BASE + 0x100Cu)
#define ETH_DMATDLAR REG32(ETH_BASE + 0x1010u)
#define ETH_DMASR REG32(ETH_BASE + 0x1014u)
#define ETH_DMAOMR REG32(ETH_BASE + 0x1018u)
#define ETH_DMAOMR_SR (1u << 1)             /* start receive */
#define ETH_DMAOMR_ST (1u << 13)            /* start transmit */
#define ETH_DMAOMR_FTF (1u << 20)           /* flush transmit FIFO */
#define ETH_DMAOMR_TSF (1u << 21)           /* transmit store and forward */
#define ETH_DMAOMR_RSF (1u << 25)           /* receive store and forward */
#define ETH_DMAIER REG32(ETH_BASE + 0x101Cu)

#endif /* STM32F7_REGS_H */
