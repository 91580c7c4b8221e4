/*
 * mps2_regs.h - the peripherals of QEMU's mps2-an500 machine that this port uses.
 *
 * Addresses as QEMU's model of the AN500 FPGA image places them (QEMU's MPS2 board
 * model; the AN500 and CMSDK documents for the register layouts):
 *
 *   0x40000000  CMSDK APB timer 0, clocked by the 25 MHz system clock: the time base
 *   0x40004000  CMSDK APB UART 0: the console (QEMU's first serial port)
 *   0x40028000  FPGA I/O: two user LEDs, standing in for the two solenoid gates
 *   0x4002F000  serial communication controller: eight MCC LEDs, LED 0 the heartbeat
 *   0xA0000000  SMSC LAN9118 Ethernet controller (a LAN9220 on the real board)
 */
#ifndef MPS2_REGS_H
#define MPS2_REGS_H

#include <stdint.h>

#define REG32(addr) (*(volatile uint32_t *)(uintptr_t)(addr))

#define MPS2_SYSCLK_HZ 25000000u

/* CMSDK APB timer: a 32-bit down counter that reloads at zero. */
#define TIMER0_BASE 0x40000000u
#define TIMER_CTRL(b) REG32((b) + 0x00u)
#define TIMER_VALUE(b) REG32((b) + 0x04u)
#define TIMER_RELOAD(b) REG32((b) + 0x08u)
#define TIMER_CTRL_EN (1u << 0)

/* CMSDK APB UART, transmit only here. */
#define UART0_BASE 0x40004000u
#define UART_DATA(b) REG32((b) + 0x00u)
#define UART_STATE(b) REG32((b) + 0x04u)
#define UART_CTRL(b) REG32((b) + 0x08u)
#define UART_BAUDDIV(b) REG32((b) + 0x10u)
#define UART_STATE_TXFULL (1u << 0)
#define UART_CTRL_TXEN (1u << 0)

/* FPGA I/O: LED0 register, bits 0 and 1 are the two user LEDs. */
#define FPGAIO_LED0 REG32(0x40028000u)
/* Serial communication controller: CFG_REG1, bits 0..7 are the MCC LEDs. */
#define SCC_CFG1 REG32(0x4002F004u)

/* System control block (Cortex-M7). */
#define SCB_VTOR REG32(0xE000ED08u)
#define SCB_CPACR REG32(0xE000ED88u)

#define LAN9118_BASE 0xA0000000u

#endif /* MPS2_REGS_H */
