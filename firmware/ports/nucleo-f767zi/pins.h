/*
 * pins.h - where everything is wired on the Nucleo-F767ZI (the lab wiring page,
 * docs/hardware-bringup-lab.md, has the same table with connector positions).
 *
 * Chosen to avoid the pins the on-board Ethernet PHY uses (PA1, PA2, PA7, PB13, PC1,
 * PC4, PC5, PG11, PG13): in particular SPI1's MOSI is taken on PB5, not on PA7.
 */
#ifndef PINS_H
#define PINS_H

#include "stm32f7_regs.h"

typedef struct {
    uint32_t port; /* PORT_A .. PORT_G */
    uint32_t pin;  /* 0..15 */
} pin_t;

/* SPI1, alternate function 5: SCK PA5, MISO PA6, MOSI PB5. */
#define PIN_SPI_SCK ((pin_t){PORT_A, 5u})
#define PIN_SPI_MISO ((pin_t){PORT_A, 6u})
#define PIN_SPI_MOSI ((pin_t){PORT_B, 5u})
#define AF_SPI1 5u

/* Encoder chip selects, active low, in the core's order: left output, left cam,
 * right output, right cam. A daisy chain uses the first only. */
#define PIN_CS0 ((pin_t){PORT_D, 14u})
#define PIN_CS1 ((pin_t){PORT_D, 15u})
#define PIN_CS2 ((pin_t){PORT_F, 12u})
#define PIN_CS3 ((pin_t){PORT_F, 13u})

/* Solenoid MOSFET gates, active high (each gate also has a pull-down resistor). */
#define PIN_SOL_LEFT ((pin_t){PORT_E, 13u})
#define PIN_SOL_RIGHT ((pin_t){PORT_E, 11u})

/* The hardware release (docs/hardware-bringup-lab.md, "Hardware release (heartbeat)"):
 * the heartbeat output (D6) triggers the external retriggerable monostable that holds
 * the solenoid drivers' enable; the core toggles it once per sample period. The
 * enable line is read back on D2 (input with pull-down: high = drivers enabled), so a
 * broken readback wire reads as "drivers off", which the bring-up step catches. */
#define PIN_HEARTBEAT ((pin_t){PORT_E, 9u})
#define PIN_DRIVERS_SENSE ((pin_t){PORT_F, 15u})

/* On-board LEDs: LD1 green, LD2 blue, LD3 red. */
#define PIN_LED_GREEN ((pin_t){PORT_B, 0u})
#define PIN_LED_BLUE ((pin_t){PORT_B, 7u})
#define PIN_LED_RED ((pin_t){PORT_B, 14u})

/* RMII to the on-board LAN8742A, alternate function 11. */
#define AF_ETH 11u
#define PHY_ADDRESS 0u

#endif /* PINS_H */
