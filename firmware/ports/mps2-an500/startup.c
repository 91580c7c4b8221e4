/*
 * startup.c - reset entry and vector table for the Cortex-M7 of QEMU's mps2-an500.
 *
 * Reset_Handler enables the FPU (this build uses the hardware floating-point ABI),
 * copies initialised data to RAM, zeroes .bss and calls main. Two interrupts are
 * used, only to wake the processor from its wait-for-interrupt: SysTick (1 ms) and the
 * LAN9118's line (a frame arrived); their handlers only acknowledge. Every other
 * exception lands in fault_handler: both solenoid outputs off, a line on the console,
 * then it stops. It does not reset: under emulation a reset would load the same
 * emulation block, and with it the same boot seed (emu_prov.h).
 */
#include <stddef.h>
#include <stdint.h>

#include "board.h"
#include "mps2_regs.h"

extern uint32_t _sidata[], _sdata[], _edata[], _sbss[], _ebss[], _estack[];
typedef void (*vector_t)(void);

int main(void);
void Reset_Handler(void);
void fault_handler(void);
void SysTick_Handler(void);
void Lan9118_Handler(void);

#define LAN9118_INT_STS REG32(LAN9118_BASE + 0x58u)

void fault_handler(void)
{
    board_solenoids_off();
    static const char msg[] = "\nFAULT: solenoids off, stopped\n";
    for (const char *p = msg; *p; p++) {
        UART_DATA(UART0_BASE) = (uint8_t)*p;
    }
    for (;;) {
        __asm__ volatile("wfi");
    }
}

void SysTick_Handler(void)
{
    /* Nothing: the tick only ends the main loop's wait. */
}

void Lan9118_Handler(void)
{
    LAN9118_INT_STS = LAN9118_INT_STS; /* acknowledge; the main loop reads the FIFO */
    __asm__ volatile("dsb" ::: "memory");
}

__attribute__((noreturn)) void Reset_Handler(void)
{
    SCB_CPACR |= 0xFu << 20; /* CP10 and CP11: full access to the FPU */
    __asm__ volatile("dsb\n isb" ::: "memory");

    /* Sizes from address differences: no comparison of pointers into different
     * objects (the linker's symbols are separate objects to the compiler). */
    size_t data_words = ((uintptr_t)_edata - (uintptr_t)_sdata) / 4u;
    for (size_t i = 0; i < data_words; i++) {
        _sdata[i] = _sidata[i];
    }
    size_t bss_words = ((uintptr_t)_ebss - (uintptr_t)_sbss) / 4u;
    for (size_t i = 0; i < bss_words; i++) {
        _sbss[i] = 0u;
    }
    (void)main();
    fault_handler(); /* main never returns */
    for (;;) {
    }
}

#define F fault_handler
/* 16 system exceptions, then the AN500's 32 interrupts (the LAN9118 is number 13). */
__attribute__((section(".isr_vector"), used)) const vector_t vector_table[16u + 32u] = {
    (vector_t)(uintptr_t)_estack, Reset_Handler, F, F, F, F, F, F,
    F, F, F, F, F, F, F, SysTick_Handler,
    F, F, F, F, F, F, F, F, F, F, F, F, F, Lan9118_Handler, F, F,
    F, F, F, F, F, F, F, F, F, F, F, F, F, F, F, F,
};
