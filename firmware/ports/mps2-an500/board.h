/*
 * board.h - the emulated board's exo_board: the device core's view of QEMU's
 * mps2-an500 with four emulated AS5048A encoders and two LEDs as solenoid gates.
 */
#ifndef BOARD_H
#define BOARD_H

#include "exo_board.h"
#include "net_stack.h"

/* Fill `b` with this board's functions; `net` is the running network stack. */
void board_fill(exo_board *b, net_stack *net);

/* Both solenoid outputs off now (also used by the fault paths). */
void board_solenoids_off(void);

#endif /* BOARD_H */
