/*
 * as5048a.c - AS5048A framing, parity and the per-sample read sequence (as5048a.h).
 */
#include "as5048a.h"

#include <string.h>

static unsigned ones(uint16_t v)
{
    unsigned n = 0;
    for (; v; v = (uint16_t)(v & (v - 1u)))
        n++;
    return n;
}

uint16_t exo_as5048a_with_parity(uint16_t frame)
{
    uint16_t low = (uint16_t)(frame & 0x7FFFu);
    return (ones(low) & 1u) ? (uint16_t)(low | EXO_AS5048A_PARITY) : low;
}

uint16_t exo_as5048a_read_command(uint16_t reg)
{
    return exo_as5048a_with_parity((uint16_t)(EXO_AS5048A_READ | (reg & EXO_AS5048A_DATA)));
}

int exo_as5048a_parity_ok(uint16_t frame) { return (ones(frame) & 1u) == 0; }

void exo_as5048a_init(exo_as5048a *e) { memset(e, 0, sizeof *e); }

/* The steps of one read, in order (as5048a.h). */
enum { STEP_CLEAR, STEP_DIAG, STEP_ANGLE, STEP_NOP, STEPS };

static uint16_t command_for(int step, int clearing)
{
    switch (step) {
    case STEP_CLEAR:
        return clearing ? exo_as5048a_read_command(EXO_AS5048A_REG_CLEAR_ERROR) : EXO_AS5048A_NOP;
    case STEP_DIAG:
        return exo_as5048a_read_command(EXO_AS5048A_REG_DIAG);
    case STEP_ANGLE:
        return exo_as5048a_read_command(EXO_AS5048A_REG_ANGLE);
    default:
        return EXO_AS5048A_NOP;
    }
}

/* Judge one encoder's answers; rx[s] is what came back during step s. */
static int judge(exo_as5048a *e, unsigned i, const uint16_t rx[STEPS], int cleared,
                 uint16_t *count)
{
    uint16_t diag = rx[STEP_ANGLE]; /* answer to the diagnostics read */
    uint16_t angle = rx[STEP_NOP];  /* answer to the angle read */
    if (cleared) {
        e->last_error[i] = (uint16_t)(rx[STEP_DIAG] & EXO_AS5048A_DATA);
        e->needs_clear[i] = 0;
    }
    *count = (uint16_t)(angle & EXO_AS5048A_DATA);
    int bad = !exo_as5048a_parity_ok(diag) || !exo_as5048a_parity_ok(angle)
              || (diag & EXO_AS5048A_ERROR_FLAG) || (angle & EXO_AS5048A_ERROR_FLAG)
              || (diag & EXO_AS5048A_DIAG_COF);
    if (bad)
        e->needs_clear[i] = 1; /* a stuck error flag would fault every later read */
    else
        e->last_diag[i] = (uint16_t)(diag & EXO_AS5048A_DATA);
    return bad;
}

unsigned exo_as5048a_read(exo_as5048a *e, const exo_board *board, int daisy_chain,
                          uint16_t counts[EXO_ENCODERS])
{
    uint16_t rx[EXO_ENCODERS][STEPS];
    int bus_failed[EXO_ENCODERS];
    int clearing[EXO_ENCODERS];
    int any_clearing = 0;
    memset(rx, 0, sizeof rx);
    for (unsigned i = 0; i < EXO_ENCODERS; i++) {
        bus_failed[i] = 0;
        clearing[i] = e->needs_clear[i];
        any_clearing |= clearing[i];
    }

    if (daisy_chain) {
        /* One chip select: each step shifts four frames, frame i for encoder i. */
        for (int s = 0; s < STEPS; s++) {
            uint16_t tx[EXO_ENCODERS], in[EXO_ENCODERS];
            if (s == STEP_CLEAR && !any_clearing)
                continue;
            for (unsigned i = 0; i < EXO_ENCODERS; i++) {
                tx[i] = command_for(s, clearing[i]);
                in[i] = 0;
            }
            if (board->spi_transfer(board->ctx, 0, tx, in, EXO_ENCODERS) != 0) {
                for (unsigned i = 0; i < EXO_ENCODERS; i++)
                    bus_failed[i] = 1;
                break;
            }
            for (unsigned i = 0; i < EXO_ENCODERS; i++)
                rx[i][s] = in[i];
        }
    } else {
        /* One chip select per encoder: one frame per call, chip select raised between. */
        for (unsigned i = 0; i < EXO_ENCODERS; i++) {
            for (int s = 0; s < STEPS; s++) {
                if (s == STEP_CLEAR && !clearing[i])
                    continue;
                uint16_t tx = command_for(s, 1);
                if (board->spi_transfer(board->ctx, i, &tx, &rx[i][s], 1) != 0) {
                    bus_failed[i] = 1;
                    break;
                }
            }
        }
    }

    unsigned faults = 0;
    for (unsigned i = 0; i < EXO_ENCODERS; i++) {
        if (bus_failed[i]) {
            counts[i] = 0;
            faults |= 1u << i;
            continue;
        }
        if (judge(e, i, rx[i], clearing[i], &counts[i]))
            faults |= 1u << i;
    }
    return faults;
}
