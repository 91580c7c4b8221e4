/*
 * as5048a_chip.h - four emulated AS5048A magnetic encoders on the simulated SPI bus.
 *
 * The linux-sim board answers the core's SPI frames the way the chips would, so that
 * the core's encoder code (command framing, parity, the pipelined answer, error
 * flags) runs exactly as on hardware; only the magnet is simulated. Facts used (ams
 * AS5048A datasheet): 16-bit frames; bit 15 even parity over bits 14..0; in a command
 * bit 14 is read (1) or write (0) and bits 13..0 the address; in an answer bit 14 is
 * the error flag and bits 13..0 the data; the answer to a command comes out during
 * the next frame; reading register 0x0001 returns the error bits and clears them.
 */
#ifndef AS5048A_CHIP_H
#define AS5048A_CHIP_H

#include <stdint.h>

#define AS5048A_NOP 0x0000u
#define AS5048A_CLEAR_ERROR 0x0001u
#define AS5048A_PROGRAMMING 0x0003u
#define AS5048A_ZERO_HI 0x0016u
#define AS5048A_ZERO_LO 0x0017u
#define AS5048A_DIAG_AGC 0x3FFDu
#define AS5048A_MAGNITUDE 0x3FFEu
#define AS5048A_ANGLE 0x3FFFu

/* Error register bits (register 0x0001). */
#define AS5048A_ERR_FRAMING 0x1u
#define AS5048A_ERR_COMMAND 0x2u
#define AS5048A_ERR_PARITY 0x4u

/* Diagnostics register bits (register 0x3FFD). */
#define AS5048A_DIAG_OCF 0x100u
#define AS5048A_DIAG_COF 0x200u
#define AS5048A_DIAG_COMP_LOW 0x400u
#define AS5048A_DIAG_COMP_HIGH 0x800u

typedef struct {
    uint16_t magnet;       /* the shaft angle the magnet presents, 0..16383 */
    int magnet_fault;      /* 1: no usable field (CORDIC overflow, field too weak) */
    uint16_t zero;         /* programmed zero position, 0..16383 */
    uint16_t programming;  /* register 0x0003 */
    uint8_t error;         /* error register: AS5048A_ERR_* */
    uint16_t next_out;     /* the frame this chip clocks out during the next transfer */
    int write_pending;     /* 1: the next frame is the data of a write to write_addr */
    uint16_t write_addr;
    uint32_t frames;       /* frames clocked through this chip */
} as5048a;

/* Power-up state: no error, zero position 0, the first answer is 0x0000. */
void as5048a_reset(as5048a *chip);

/* What the magnet presents now; `fault` simulates a field the chip cannot measure. */
void as5048a_set_magnet(as5048a *chip, uint16_t angle, int fault);

/* One 16-bit frame with chip select held low: returns the frame clocked out while
 * `in` was clocked in (the answer to the previous frame's command). */
uint16_t as5048a_frame(as5048a *chip, uint16_t in);

/* A frame with bit 15 set so that the 16 bits have even parity. */
uint16_t as5048a_with_parity(uint16_t frame15);

#endif /* AS5048A_CHIP_H */
