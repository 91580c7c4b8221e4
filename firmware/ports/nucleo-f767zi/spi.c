/* spi.c - SPI1 registers (RM0410 "Serial peripheral interface"). */
#include "spi.h"

#include "clock.h"
#include "gpio.h"

/* AS5048A timing (ams datasheet): CSn falling to the first clock edge and CSn high
 * between frames each at least 350 ns. 48 cycles at 96 MHz is 500 ns. */
#define CS_SETUP_CYCLES 48u
#define CS_HIGH_CYCLES 48u
#define FRAME_TIMEOUT_CYCLES (CLOCK_HCLK_HZ / 10000u) /* 100 us; a frame takes 5.3 us */
#define SPI_BR_DIV32 4u                               /* 96 MHz / 32 = 3 MHz */

/* Chip select `chip` (0..3, the core's order). A function, not a table: the pin
 * macros are compound literals, which ISO C does not allow in a static initialiser. */
static pin_t cs_pin(unsigned chip)
{
    switch (chip) {
    case 0u:
        return PIN_CS0;
    case 1u:
        return PIN_CS1;
    case 2u:
        return PIN_CS2;
    default:
        return PIN_CS3;
    }
}

void spi_init(void)
{
    for (unsigned i = 0; i < SPI_CHIPS; i++) {
        gpio_output(cs_pin(i), 1); /* deselected */
    }
    gpio_alternate(PIN_SPI_SCK, AF_SPI1, 0);
    gpio_alternate(PIN_SPI_MISO, AF_SPI1, 1);
    gpio_alternate(PIN_SPI_MOSI, AF_SPI1, 0);
    RCC_APB2ENR |= RCC_APB2ENR_SPI1EN;
    (void)RCC_APB2ENR;
    SPI1_CR1 = 0u;
    SPI1_CR2 = SPI_CR2_DS_16BIT; /* FRXTH 0: RXNE at 16 bits */
    SPI1_CR1 = SPI_CR1_CPHA | SPI_CR1_MSTR | (SPI_BR_DIV32 << SPI_CR1_BR_SHIFT) | SPI_CR1_SSM |
               SPI_CR1_SSI;
    SPI1_CR1 |= SPI_CR1_SPE;
}

static int wait_flag(uint32_t flag, int set)
{
    uint32_t start = DWT_CYCCNT;
    while (((SPI1_SR & flag) != 0u) != (set != 0)) {
        if (DWT_CYCCNT - start > FRAME_TIMEOUT_CYCLES) {
            return -1;
        }
    }
    return 0;
}

static void drain(void)
{
    while (SPI1_SR & SPI_SR_RXNE) {
        (void)SPI1_DR16;
    }
    (void)SPI1_SR; /* DR then SR read clears an overrun */
}

int spi_transfer(unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n)
{
    if (chip >= SPI_CHIPS || n == 0u) {
        return -1;
    }
    drain();
    gpio_write(cs_pin(chip), 0);
    clock_delay_cycles(CS_SETUP_CYCLES);
    int rc = 0;
    for (size_t i = 0; i < n && rc == 0; i++) {
        if (wait_flag(SPI_SR_TXE, 1) != 0) {
            rc = -1;
            break;
        }
        SPI1_DR16 = tx[i];
        if (wait_flag(SPI_SR_RXNE, 1) != 0) {
            rc = -1;
            break;
        }
        rx[i] = SPI1_DR16;
    }
    if (wait_flag(SPI_SR_BSY, 0) != 0) {
        rc = -1;
    }
    gpio_write(cs_pin(chip), 1);
    clock_delay_cycles(CS_HIGH_CYCLES);
    if (rc != 0) {
        drain();
    }
    return rc;
}
