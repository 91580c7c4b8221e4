/* sbc_gpio.c - solenoid, heartbeat and drivers-enable lines with libgpiod v1. */
#include "sbc_gpio.h"

#include <errno.h>
#include <gpiod.h>
#include <stdio.h>
#include <string.h>

#include "wire.h"

#define CONSUMER "exo-sbc"

/* Request line `offset` as an output at 0 (`output` != 0) or as an input. */
static struct gpiod_line *request(struct gpiod_chip *chip, unsigned offset, const char *what,
                                  int output, char *err, size_t errlen)
{
    struct gpiod_line *line = gpiod_chip_get_line(chip, offset);
    if (line == NULL) {
        snprintf(err, errlen, "%s: no line %u on this chip: %s", what, offset, strerror(errno));
        return NULL;
    }
    int rc = output ? gpiod_line_request_output(line, CONSUMER, 0)
                    : gpiod_line_request_input(line, CONSUMER);
    if (rc < 0) {
        snprintf(err, errlen, "%s: line %u cannot be requested as an %s: %s", what, offset,
                 output ? "output" : "input", strerror(errno));
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
    int ok = (g->left = request(g->chip, o->line_left, "left solenoid", 1, err, errlen)) &&
             (g->right = request(g->chip, o->line_right, "right solenoid", 1, err, errlen));
    if (ok && o->has_heartbeat_line) {
        ok = (g->heartbeat = request(g->chip, o->line_heartbeat, "heartbeat", 1, err,
                                     errlen)) != NULL;
    }
    if (ok && o->has_drivers_line) {
        ok = (g->drivers = request(g->chip, o->line_drivers, "drivers enable readback", 0,
                                   err, errlen)) != NULL;
    }
    if (!ok) {
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

void sbc_gpio_heartbeat(sbc_gpio *g, int level)
{
    if (g->heartbeat != NULL) {
        gpiod_line_set_value(g->heartbeat, level ? 1 : 0);
    }
}

uint32_t sbc_gpio_drivers_status(sbc_gpio *g)
{
    if (g->drivers == NULL) {
        return 0u;
    }
    int v = gpiod_line_get_value(g->drivers);
    if (v < 0) {
        g->drivers_read_errors++;
        return 0u;
    }
    return v == 0 ? EXO_STATUS_DRIVERS_OFF : 0u;
}

static void release(struct gpiod_line **line, int drive_low)
{
    if (*line != NULL) {
        if (drive_low) {
            gpiod_line_set_value(*line, 0);
        }
        gpiod_line_release(*line);
        *line = NULL;
    }
}

void sbc_gpio_close(sbc_gpio *g)
{
    release(&g->left, 1);
    release(&g->right, 1);
    release(&g->heartbeat, 1);
    release(&g->drivers, 0);
    if (g->chip != NULL) {
        gpiod_chip_close(g->chip);
        g->chip = NULL;
    }
}
