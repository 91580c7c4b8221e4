/*
 * board.h - the linux-sim board: UDP sockets and the monotonic clock of Linux, four
 * emulated AS5048A chips on the SPI bus, and the simulated wearer (plant.h) as the
 * mechanism the solenoids act on.
 */
#ifndef LINUX_SIM_BOARD_H
#define LINUX_SIM_BOARD_H

#include <stdint.h>

#include "as5048a_chip.h"
#include "exo_board.h"
#include "plant.h"

/* A step of the simulated wearer this long takes a good part of the 2 ms a sample may
 * be late: counted, to tell the wearer's cost from the core's. */
#define LINUX_SIM_SLOW_STEP_US 1000u

/* The external retriggerable monostable on the solenoid drivers' enable: it holds the
 * drivers on for this long after each heartbeat edge (docs/hardware-bringup-lab.md);
 * the same 30 ms as the Python simulator's HEARTBEAT_HOLD_S. */
#define LINUX_SIM_HEARTBEAT_HOLD_US 30000u

typedef struct {
    int sock;
    plant *plant;
    as5048a chips[4];
    plant_reading reading; /* what the mechanism and encoders show this period */
    int have_reading;
    int solenoids[2];      /* as last driven by the firmware */
    int heartbeat_level;   /* the heartbeat output as last driven */
    int have_edge;         /* an edge has happened since boot (drivers off before) */
    uint64_t last_edge_us; /* when the latest heartbeat edge happened */
    int drivers_on;        /* the monostable's output at the latest sample period */
    uint64_t driver_cutoffs; /* drivers' enable went from on to off */
    int hold;              /* drive the solenoids but do not advance the wearer (the
                              core's release at init and at stop) */
    unsigned rate_factor;  /* fault probe: the plant steps once every this many samples */
    uint64_t drive_calls;  /* set_solenoids calls while running */
    int plant_failed;      /* the wearer is gone: the port exits */
    int finished;          /* the script or file has ended with this period's step; the
                              core builds and sends that sample in the same poll */
    uint64_t periods;      /* sample periods the plant was stepped */
    uint64_t step_max_us;  /* longest step of the wearer (pipe round trip included) */
    uint64_t slow_steps;   /* steps longer than LINUX_SIM_SLOW_STEP_US */
    uint64_t spi_frames;
    uint64_t sends;
    uint64_t send_errors;
    uint64_t receive_errors;
    uint32_t host_ip;      /* host byte order */
} linux_sim_board;

/* Fill `board` with this port's functions around `ctx` (socket and plant set). */
void linux_sim_board_init(linux_sim_board *ctx, exo_board *board, int sock, plant *p,
                          uint32_t host_ip);

uint64_t linux_sim_now_us(void);

#endif /* LINUX_SIM_BOARD_H */
