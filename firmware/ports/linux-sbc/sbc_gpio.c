/* sbc_gpio.c - solenoid lines with libgpiod v1. */
#include "sbc_gpio.h"

#include <errno.h>
#include <gpiod.h>
#include <stdio.h>
#include <string.h>

#define CONSUMER "exo-sbc"

static struct gpiod_line *request(struct gpiod_chip *chip, unsigned offset, const char *side,
                                  char *err, size_t errlen)
{
    struct gpiod_line *line = gpiod_chip_get_line(chip, offset);
    if (line == NULL) {
        snprintf(err, errlen, "%s solenoid: no line %u on this chip: %s", side, offset,
                 strerror(errno));
        return NULL;
    }
    if (gpiod_line_request_output(line, CONSUMER, 0) < 0) {
        snprintf(err, errlen, "%s solenoid: line %u cannot be requested as an output: %s",
                 side, offset, strerror(errno));
        return NULL;
    }
    return line;
}

int sbc_gpio_open(sbc_gpio *g, const sbc_options *o, char *err, size_t errlen)
{
    memset(g, 0, sizeof *g);
    g->chip = gpiod_chip_open_lookup(o->gpiochip);
    if (g->chip == NULL) {
        snprintf(err, errlen, "%s: no such gpiochip: %s", o->gpiochip, strerror(errno));
        return -1;
    }
    g->left = request(g->chip, o->line_left, "left", err, errlen);
    if (g->left != NULL) {
        g->right = request(g->chip, o->line_right, "right", err, errlen);
    }
    if (g->left == NULL || g->right == NULL) {
        sbc_gpio_close(g);
        return -1;
    }
    return 0;
}

void sbc_gpio_set(sbc_gpio *g, int left, int right)
{
    gpiod_line_set_value(g->left, left ? 1 : 0);
    gpiod_line_set_value(g->right, right ? 1 : 0);
}

void sbc_gpio_close(sbc_gpio *g)
{
    if (g->left != NULL) {
        gpiod_line_set_value(g->left, 0);
        gpiod_line_release(g->left);
        g->left = NULL;
    }
    if (g->right != NULL) {
        gpiod_line_set_value(g->right, 0);
        gpiod_line_release(g->right);
        g->right = NULL;
    }
    if (g->chip != NULL) {
        gpiod_chip_close(g->chip);
        g->chip = NULL;
    }
}
