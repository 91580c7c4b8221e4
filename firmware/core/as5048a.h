/*
 * as5048a.h - reading the four AS5048A magnetic encoders over SPI.
 *
 * Frames are 16 bits, MSB first. A command frame is [even parity | read=1/write=0 |
 * 14-bit address]; an answer frame is [even parity | error flag | 14-bit data]. The
 * bus is pipelined: the answer to a command comes out during the *next* frame. Parity
 * is even over bits 14..0, i.e. bit 15 makes the frame's count of ones even.
 *
 * Per sample, for each encoder, the core clocks (see exo_as5048a_read):
 *   [0x4001 read clear-error register  - only after that encoder reported a fault]
 *    0x7FFD read diagnostics (0x3FFD)   answer: ignored (or the error register)
 *    0xFFFF read angle (0x3FFF)         answer: diagnostics
 *    0x0000 NOP                         answer: angle
 * so the angle is read fresh every period (not one period late, as continuous 0xFFFF
 * reads would give) and the CORDIC-overflow bit is checked with it.
 */
#ifndef EXO_AS5048A_H
#define EXO_AS5048A_H

#include <stdint.h>

#include "exo_board.h"

#define EXO_ENCODERS 4u /* left output, left cam, right output, right cam */

#define EXO_AS5048A_REG_CLEAR_ERROR 0x0001u
#define EXO_AS5048A_REG_DIAG 0x3FFDu
#define EXO_AS5048A_REG_MAGNITUDE 0x3FFEu
#define EXO_AS5048A_REG_ANGLE 0x3FFFu
#define EXO_AS5048A_NOP 0x0000u
#define EXO_AS5048A_READ 0x4000u       /* bit 14 of a command: read */
#define EXO_AS5048A_ERROR_FLAG 0x4000u /* bit 14 of an answer: previous command failed */
#define EXO_AS5048A_PARITY 0x8000u
#define EXO_AS5048A_DATA 0x3FFFu
#define EXO_AS5048A_DIAG_COF 0x0200u  /* diagnostics bit 9: CORDIC overflow */
#define EXO_AS5048A_DIAG_COMP_HIGH 0x0800u /* field too strong (reported, not a fault) */
#define EXO_AS5048A_DIAG_COMP_LOW 0x0400u  /* field too weak (reported, not a fault) */

/* `frame` with bit 15 set or cleared so that the 16 bits hold an even number of ones. */
uint16_t exo_as5048a_with_parity(uint16_t frame);

/* The read command for register `reg` (0..0x3FFF), parity included: 0x3FFF -> 0xFFFF,
 * 0x0001 -> 0x4001, 0x3FFD -> 0x7FFD. */
uint16_t exo_as5048a_read_command(uint16_t reg);

/* 1 if an answer frame's parity is right, else 0. */
int exo_as5048a_parity_ok(uint16_t frame);

typedef struct {
    uint8_t needs_clear[EXO_ENCODERS]; /* clear the error flag before the next read */
    uint16_t last_error[EXO_ENCODERS]; /* error register read at the last clear */
    uint16_t last_diag[EXO_ENCODERS];  /* diagnostics/AGC of the last good read */
} exo_as5048a;

void exo_as5048a_init(exo_as5048a *e);

/* Read all four angles: `counts` gets the 14 data bits of each angle answer (0 if the
 * bus failed), whatever their quality. Returns a mask, bit i set if encoder i's reading
 * is unusable (bus failure, parity error, error flag, CORDIC overflow). `daisy_chain`
 * selects one transfer of 4 frames (chip 0) per step instead of one frame per chip. */
unsigned exo_as5048a_read(exo_as5048a *e, const exo_board *board, int daisy_chain,
                          uint16_t counts[EXO_ENCODERS]);

#endif /* EXO_AS5048A_H */
