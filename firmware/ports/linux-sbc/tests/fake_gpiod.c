/*
 * fake_gpiod.c - the libgpiod v1 calls sbc_gpio.c makes, recorded in memory so the unit
 * tests can check which lines were requested how, and what was written to them.
 * Linked into the test binary instead of -lgpiod. Test equipment only.
 */
#include "fake_gpiod.h"

#include <errno.h>
#include <string.h>

struct gpiod_chip {
    int open;
};

static struct gpiod_chip chip;
fake_line fake_lines[FAKE_LINES];

void fake_gpiod_reset(void)
{
    memset(&chip, 0, sizeof chip);
    memset(fake_lines, 0, sizeof fake_lines);
    for (unsigned i = 0; i < FAKE_LINES; i++) {
        fake_lines[i].offset = i;
        fake_lines[i].value = -1;
    }
}

struct gpiod_chip *gpiod_chip_open_lookup(const char *descr)
{
    (void)descr;
    chip.open = 1;
    return &chip;
}

void gpiod_chip_close(struct gpiod_chip *c)
{
    c->open = 0;
}

struct gpiod_line *gpiod_chip_get_line(struct gpiod_chip *c, unsigned int offset)
{
    (void)c;
    if (offset >= FAKE_LINES) {
        errno = EINVAL;
        return NULL;
    }
    return (struct gpiod_line *)&fake_lines[offset];
}

int gpiod_line_request_output(struct gpiod_line *line, const char *consumer, int value)
{
    (void)consumer;
    fake_line *l = (fake_line *)line;
    if (l->requested) {
        errno = EBUSY;
        return -1;
    }
    l->requested = 1;
    l->output = 1;
    l->value = value;
    return 0;
}

int gpiod_line_request_input(struct gpiod_line *line, const char *consumer)
{
    (void)consumer;
    fake_line *l = (fake_line *)line;
    if (l->requested) {
        errno = EBUSY;
        return -1;
    }
    l->requested = 1;
    l->output = 0;
    return 0;
}

int gpiod_line_set_value(struct gpiod_line *line, int value)
{
    fake_line *l = (fake_line *)line;
    if (!l->requested || !l->output) {
        return -1;
    }
    if (l->value != value) {
        l->edges++;
    }
    l->value = value;
    return 0;
}

int gpiod_line_get_value(struct gpiod_line *line)
{
    fake_line *l = (fake_line *)line;
    if (!l->requested || l->fail_reads) {
        return -1;
    }
    return l->output ? l->value : l->input;
}

void gpiod_line_release(struct gpiod_line *line)
{
    ((fake_line *)line)->requested = 0;
}
