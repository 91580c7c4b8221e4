/* fake_gpiod.h - the in-memory libgpiod of the unit tests (fake_gpiod.c). */
#ifndef FAKE_GPIOD_H
#define FAKE_GPIOD_H

#include <gpiod.h>

#define FAKE_LINES 64

/* One line; offsets 0..FAKE_LINES-1 exist. The first member lets a struct gpiod_line *
 * handed out by the fake point at it. */
typedef struct {
    unsigned offset;
    int requested;
    int output;
    int value;      /* last value written (outputs); -1 never */
    unsigned edges; /* changes of value written */
    int input;      /* what an input reads */
    int fail_reads; /* make gpiod_line_get_value fail */
} fake_line;

extern fake_line fake_lines[FAKE_LINES];
void fake_gpiod_reset(void);

#endif /* FAKE_GPIOD_H */
