/*
 * as5048a_chip.c - the emulated encoder chip (see as5048a_chip.h for the facts it follows).
 */
#include "as5048a_chip.h"

static unsigned ones(uint16_t v) {
    unsigned n = 0;
    while (v) {
        n += v & 1u;
        v >>= 1;
    }
    return n;
}

uint16_t as5048a_with_parity(uint16_t frame15) {
    frame15 &= 0x7FFFu;
    return (uint16_t)(frame15 | ((ones(frame15) & 1u) << 15));
}

static uint16_t answer(const as5048a *chip, uint16_t data) {
    uint16_t ef = chip->error ? 0x4000u : 0u;
    return as5048a_with_parity((uint16_t)(ef | (data & 0x3FFFu)));
}

void as5048a_reset(as5048a *chip) {
    chip->magnet = 0;
    chip->magnet_fault = 0;
    chip->zero = 0;
    chip->programming = 0;
    chip->error = 0;
    chip->next_out = 0;
    chip->write_pending = 0;
    chip->write_addr = 0;
    chip->frames = 0;
}

void as5048a_set_magnet(as5048a *chip, uint16_t angle, int fault) {
    chip->magnet = (uint16_t)(angle & 0x3FFFu);
    chip->magnet_fault = fault != 0;
}

/* Register contents as a read would return them; -1 for an address the chip lacks. */
static long read_register(const as5048a *chip, uint16_t addr) {
    switch (addr) {
    case AS5048A_NOP:
        return 0;
    case AS5048A_CLEAR_ERROR:
        return chip->error;
    case AS5048A_PROGRAMMING:
        return chip->programming;
    case AS5048A_ZERO_HI:
        return (chip->zero >> 6) & 0xFFu;
    case AS5048A_ZERO_LO:
        return chip->zero & 0x3Fu;
    case AS5048A_DIAG_AGC:
        /* Offset compensation done; a good field gives a mid-range AGC value. */
        return chip->magnet_fault ? (AS5048A_DIAG_OCF | AS5048A_DIAG_COF |
                                     AS5048A_DIAG_COMP_HIGH | 0xFFu)
                                  : (AS5048A_DIAG_OCF | 0x80u);
    case AS5048A_MAGNITUDE:
        return chip->magnet_fault ? 0 : 0x0FA0;
    case AS5048A_ANGLE:
        return (chip->magnet - chip->zero) & 0x3FFFu;
    default:
        return -1;
    }
}

static int write_register(as5048a *chip, uint16_t addr, uint16_t value) {
    switch (addr) {
    case AS5048A_PROGRAMMING:
        chip->programming = value & 0x4Du;
        return 0;
    case AS5048A_ZERO_HI:
        chip->zero = (uint16_t)(((value & 0xFFu) << 6) | (chip->zero & 0x3Fu));
        return 0;
    case AS5048A_ZERO_LO:
        chip->zero = (uint16_t)((chip->zero & 0x3FC0u) | (value & 0x3Fu));
        return 0;
    default:
        return -1;
    }
}

uint16_t as5048a_frame(as5048a *chip, uint16_t in) {
    uint16_t out = chip->next_out;
    chip->frames++;
    if (ones(in) & 1u) {
        /* A command (or data) with a parity error is not executed. */
        chip->error |= AS5048A_ERR_PARITY;
        chip->write_pending = 0;
        chip->next_out = answer(chip, 0);
        return out;
    }
    if (chip->write_pending) {
        /* The data frame of a write: the old content comes out next, then the new. */
        long old = read_register(chip, chip->write_addr);
        chip->write_pending = 0;
        if (in & 0x4000u) {
            chip->error |= AS5048A_ERR_FRAMING; /* bit 14 of a data frame must be 0 */
        } else if (write_register(chip, chip->write_addr, in & 0x3FFFu) != 0) {
            chip->error |= AS5048A_ERR_COMMAND;
        }
        chip->next_out = answer(chip, (uint16_t)(old < 0 ? 0 : old));
        return out;
    }
    uint16_t addr = in & 0x3FFFu;
    if (in & 0x4000u) {
        long value = read_register(chip, addr);
        if (value < 0) {
            chip->error |= AS5048A_ERR_COMMAND;
            chip->next_out = answer(chip, 0);
        } else if (addr == AS5048A_CLEAR_ERROR) {
            chip->error = 0; /* the answer carries the bits it cleared */
            chip->next_out = answer(chip, (uint16_t)value);
        } else {
            chip->next_out = answer(chip, (uint16_t)value);
        }
        return out;
    }
    if (addr == AS5048A_NOP) {
        chip->next_out = answer(chip, 0);
        return out;
    }
    long old = read_register(chip, addr);
    if (old < 0 || addr == AS5048A_DIAG_AGC || addr == AS5048A_MAGNITUDE ||
        addr == AS5048A_ANGLE || addr == AS5048A_CLEAR_ERROR) {
        chip->error |= AS5048A_ERR_COMMAND; /* read-only or absent register */
        chip->next_out = answer(chip, 0);
        return out;
    }
    chip->write_pending = 1;
    chip->write_addr = addr;
    chip->next_out = answer(chip, (uint16_t)old);
    return out;
}
