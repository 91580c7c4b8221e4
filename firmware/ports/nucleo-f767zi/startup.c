/*
 * startup.c - reset entry and vector table for the STM32F767 (Cortex-M7).
 *
 * Reset_Handler enables the FPU (this build uses the hardware floating-point ABI),
 * copies initialised data from flash, zeroes .bss and calls main. Every exception and
 * interrupt not otherwise handled (none are enabled) lands in fault_handler, which
 * switches both solenoid gates off and resets the chip: a fault never leaves a
 * solenoid energised, and the board comes back up in its safe state.
 */
#include <stdint.h>

#include "pins.h"
#include "stm32f7_regs.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
typedef void (*vector_t)(void);

int main(void);
void Reset_Handler(void);
extern const vector_t vector_table[];
void fault_handler(void);

#define IRQ_COUNT 110u /* STM32F76x/77x vector table: 110 peripheral interrupts */

void fault_handler(void)
{
    /* Direct register writes: nothing here may depend on state that may be damaged. */
    GPIO_BSRR(PIN_SOL_LEFT.port) = 1u << (PIN_SOL_LEFT.pin + 16u);
    GPIO_BSRR(PIN_SOL_RIGHT.port) = 1u << (PIN_SOL_RIGHT.pin + 16u);
    __asm__ volatile("dsb" ::: "memory");
    SCB_AIRCR = SCB_AIRCR_RESET;
    for (;;) {
    }
}

__attribute__((noreturn)) void Reset_Handler(void)
{
    /* Point exceptions at this table: the F7 boots through its flash alias at
     * 0x00200000, and address 0 is ITCM RAM, not a copy of the vectors. */
    SCB_VTOR = (uint32_t)(uintptr_t)vector_table;
    SCB_CPACR |= 0xFu << 20; /* CP10 and CP11: full access to the FPU */
    __asm__ volatile("dsb\n isb" ::: "memory");

    uint32_t *src = &_sidata;
    for (uint32_t *dst = &_sdata; dst < &_edata;) {
        *dst++ = *src++;
    }
    for (uint32_t *dst = &_sbss; dst < &_ebss;) {
        *dst++ = 0u;
    }
    (void)main();
    fault_handler(); /* main never returns; if it did, reset */
    for (;;) {
    }
}

__attribute__((section(".isr_vector"), used)) const vector_t vector_table[16u + IRQ_COUNT] = {
    [0] = (vector_t)(uintptr_t)&_estack,
    [1] = Reset_Handler,
    [2] = fault_handler, /* NMI */
    [3] = fault_handler, /* HardFault */
    [4] = fault_handler, /* MemManage */
    [5] = fault_handler, /* BusFault */
    [6] = fault_handler, /* UsageFault */
    [11] = fault_handler, /* SVCall */
    [12] = fault_handler, /* DebugMonitor */
    [14] = fault_handler, /* PendSV */
    [15] = fault_handler, /* SysTick */
    [16 ... 16u + IRQ_COUNT - 1u] = fault_handler,
};
