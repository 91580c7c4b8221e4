/*
 * board.h - the Nucleo-F767ZI's exo_board: the device core's view of this board.
 */
#ifndef BOARD_H
#define BOARD_H

#include "exo_board.h"
#include "net/net_stack.h"

/* Fill `b` with this board's functions; `net` is the running network stack. */
void board_fill(exo_board *b, net_stack *net);

/* Drive both solenoid gates low now (also used by the fault paths). */
void board_solenoids_off(void);

#endif /* BOARD_H */
