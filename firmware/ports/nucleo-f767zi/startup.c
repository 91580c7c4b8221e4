/*
 * startup.c - reset entry and vector table for the STM32F767 (Cortex-M7).
 *
 * Reset_Handler enables the FPU (this build uses the hardware floating-point ABI),
 * copies initialised data from flash, zeroes .bss and calls main. Every exception and
 * interrupt not otherwise handled (none are enabled) lands in fault_handler, which
 * switches both solenoid gates off and resets the chip: a fault never leaves a
 * solenoid energised, and the board comes back up in its safe state.
 */
#include <stddef.h>
#include <stdint.h>

#include "pins.h"
#include "stm32f7_regs.h"

/* Linker-script symbols (stm32f767zi.ld). Only their addresses mean anything, and they
 * name different objects, so they are never compared as pointers (undefined in C);
 * the lengths below are computed from the addresses as integers. */
extern uint32_t _sidata[], _sdata[], _edata[], _sbss[], _ebss[], _estack[];
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

    size_t data_words = ((uintptr_t)_edata - (uintptr_t)_sdata) / sizeof(uint32_t);
    for (size_t i = 0; i < data_words; i++) {
        _sdata[i] = _sidata[i];
    }
    size_t bss_words = ((uintptr_t)_ebss - (uintptr_t)_sbss) / sizeof(uint32_t);
    for (size_t i = 0; i < bss_words; i++) {
        _sbss[i] = 0u;
    }
    (void)main();
    fault_handler(); /* main never returns; if it did, reset */
    for (;;) {
    }
}

/* IRQ_COUNT times fault_handler, spelled out: ISO C has no range initialiser. The
 * typedef fails the build if the count is not IRQ_COUNT. */
#define FH2 fault_handler, fault_handler
#define FH10 FH2, FH2, FH2, FH2, FH2
#define FH110 FH10, FH10, FH10, FH10, FH10, FH10, FH10, FH10, FH10, FH10, FH10
typedef char fh110_is_irq_count[sizeof((vector_t[]){FH110}) / sizeof(vector_t) == IRQ_COUNT
                                    ? 1
                                    : -1];

__attribute__((section(".isr_vector"), used)) const vector_t vector_table[16u + IRQ_COUNT] = {
    [0] = (vector_t)(uintptr_t)_estack,
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
    [16] = FH110,
};
