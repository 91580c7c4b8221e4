/*
 * board.h - the Nucleo-F767ZI's exo_board: the device core's view of this board.
 */
#ifndef BOARD_H
#define BOARD_H

#include <stdint.h>

#include "exo_board.h"
#include "net/net_stack.h"

/* Fill `b` with this board's functions; `net` is the running network stack. */
void board_fill(exo_board *b, net_stack *net);

/* Drive both solenoid gates low now (also used by the fault paths). */
void board_solenoids_off(void);

/* First thing at start-up: gates low, heartbeat low, the enable readback as an input. */
void board_pins_init(void);

/* The CHALLENGE identity: the chip's 96-bit unique ID, zero-padded to 16 bytes. */
void board_unique_id(uint8_t out[16]);

#endif /* BOARD_H */
