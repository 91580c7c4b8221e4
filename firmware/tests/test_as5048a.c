/*
 * test_as5048a.c - AS5048A framing: parity of every possible 16-bit frame against an
 * independent bit count, the command words, the per-sample read sequence through the
 * pipelined fake encoders, fault detection (parity, error flag, CORDIC overflow, bus)
 * and error clearing, and one chip select per encoder versus a daisy chain.
 */
#include <string.h>

#include "as5048a.h"
#include "check.h"
#include "fake_board.h"

static void parity(void)
{
    unsigned wrong_with = 0, wrong_ok = 0;
    for (uint32_t v = 0; v <= 0xFFFFu; v++) {
        uint16_t f = (uint16_t)v;
        uint16_t p = exo_as5048a_with_parity(f);
        /* bits 14..0 untouched, bit 15 makes the count of ones even */
        if ((p & 0x7FFFu) != (f & 0x7FFFu) || !fake_parity_even(p))
            wrong_with++;
        if (exo_as5048a_parity_ok(f) != fake_parity_even(f))
            wrong_ok++;
    }
    CHECK_EQ(wrong_with, 0);
    CHECK_EQ(wrong_ok, 0);
    /* The command words of the datasheet. */
    CHECK_EQ(exo_as5048a_read_command(EXO_AS5048A_REG_ANGLE), 0xFFFF);
    CHECK_EQ(exo_as5048a_read_command(EXO_AS5048A_REG_CLEAR_ERROR), 0x4001);
    CHECK_EQ(exo_as5048a_read_command(EXO_AS5048A_REG_DIAG), 0x7FFD);
    CHECK_EQ(exo_as5048a_read_command(EXO_AS5048A_REG_MAGNITUDE), 0x7FFE);
    CHECK(fake_parity_even(EXO_AS5048A_NOP));
}

static fake_board fb;

static void reset_logs(void)
{
    for (unsigned i = 0; i < 4; i++)
        fb.enc[i].n_log = 0;
    fb.spi_calls = 0;
}

static void read_sequence(int daisy)
{
    fake_init(&fb);
    fb.daisy_chain = daisy;
    exo_board b = fake_interface(&fb, 0);
    exo_as5048a e;
    exo_as5048a_init(&e);
    uint16_t counts[4];

    unsigned faults = exo_as5048a_read(&e, &b, daisy, counts);
    CHECK_EQ(faults, 0);
    for (unsigned i = 0; i < 4; i++) {
        CHECK_EQ(counts[i], fb.enc[i].angle); /* fresh: read in this call, not the last */
        CHECK_EQ(fb.enc[i].n_log, 3);
        CHECK_EQ(fb.enc[i].log[0], 0x7FFD);
        CHECK_EQ(fb.enc[i].log[1], 0xFFFF);
        CHECK_EQ(fb.enc[i].log[2], 0x0000);
    }
    CHECK_EQ(fb.spi_calls, daisy ? 3 : 12); /* 3 transfers of 4 frames, or 12 of 1 */
    CHECK_EQ(fb.spi_wrong_shape, 0);

    /* The angle moves between samples: each read reports the new value at once. */
    reset_logs();
    fb.enc[2].angle = 16383;
    fb.enc[3].angle = 0;
    faults = exo_as5048a_read(&e, &b, daisy, counts);
    CHECK_EQ(faults, 0);
    CHECK_EQ(counts[2], 16383);
    CHECK_EQ(counts[3], 0);

    /* Error flag (e.g. a framing error): fault now, cleared with 0x4001 on the next
     * read, which is good again; the error register's content is kept. */
    fb.enc[1].error_flag = 1;
    fb.enc[1].error_reg = 1; /* framing */
    reset_logs();
    faults = exo_as5048a_read(&e, &b, daisy, counts);
    CHECK_EQ(faults, 1u << 1);
    CHECK_EQ(e.needs_clear[1], 1);
    reset_logs();
    faults = exo_as5048a_read(&e, &b, daisy, counts);
    CHECK_EQ(faults, 0);
    CHECK_EQ(fb.enc[1].log[0], 0x4001);
    CHECK_EQ(fb.enc[1].n_log, 4);
    CHECK_EQ(e.last_error[1], 1);
    CHECK_EQ(e.needs_clear[1], 0);
    CHECK_EQ(counts[1], fb.enc[1].angle);
    /* The others were not disturbed: in a chain they got a NOP, else nothing extra. */
    CHECK_EQ(fb.enc[0].n_log, daisy ? 4 : 3);
    CHECK_EQ(fb.enc[0].log[0], daisy ? 0x0000 : 0x7FFD);

    /* Parity error on the angle answer: fault for as long as it lasts. */
    fb.enc[3].corrupt_angle = 1;
    faults = exo_as5048a_read(&e, &b, daisy, counts);
    CHECK_EQ(faults, 1u << 3);
    CHECK(counts[3] < 16384); /* masked to 14 bits even when faulty */
    fb.enc[3].corrupt_angle = 0;
    faults = exo_as5048a_read(&e, &b, daisy, counts); /* clears, reads well */
    CHECK_EQ(faults, 0);

    /* CORDIC overflow in the diagnostics register. */
    fb.enc[0].diag |= EXO_AS5048A_DIAG_COF;
    faults = exo_as5048a_read(&e, &b, daisy, counts);
    CHECK_EQ(faults, 1u << 0);
    fb.enc[0].diag &= (uint16_t)~EXO_AS5048A_DIAG_COF;
    /* Field too strong/weak is reported in diag but is not a fault by itself. */
    fb.enc[0].diag |= EXO_AS5048A_DIAG_COMP_HIGH;
    exo_as5048a_read(&e, &b, daisy, counts);
    faults = exo_as5048a_read(&e, &b, daisy, counts);
    CHECK_EQ(faults, 0);
    CHECK(e.last_diag[0] & EXO_AS5048A_DIAG_COMP_HIGH);

    /* The bus fails: every encoder on it is faulty, counts 0. */
    fb.bus_fail = 1;
    faults = exo_as5048a_read(&e, &b, daisy, counts);
    CHECK_EQ(faults, 0xF);
    CHECK_EQ(counts[0] | counts[1] | counts[2] | counts[3], 0);
    fb.bus_fail = 0;
    CHECK_EQ(exo_as5048a_read(&e, &b, daisy, counts), 0);

    /* No command frame the core sent had wrong parity. */
    CHECK_EQ(fb.frames_bad_parity, 0);
    CHECK(fb.frames > 0);
}

void test_as5048a(void)
{
    parity();
    read_sequence(0);
    read_sequence(1);
}
