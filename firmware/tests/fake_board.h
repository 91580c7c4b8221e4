/*
 * fake_board.h - a test double for exo_board: a clock the test moves, queues of
 * datagrams in and out, solenoid outputs, and four AS5048A models that answer SPI
 * frames the way the datasheet says (pipelined answers, even parity, a sticky error
 * flag cleared by reading register 0x0001, diagnostics with the CORDIC-overflow bit).
 *
 * Everything is inspectable, so the tests check what the core did to the "hardware",
 * not only what it says about it.
 */
#ifndef EXO_TEST_FAKE_BOARD_H
#define EXO_TEST_FAKE_BOARD_H

#include <stddef.h>
#include <stdint.h>

#include "exo_board.h"

#define FAKE_QUEUE 64
#define FAKE_FRAME_LOG 64

typedef struct {
    uint8_t data[256];
    long len; /* what receive returns (may exceed the stored bytes: oversize) */
    exo_endpoint peer;
    uint64_t at_us; /* sent: clock at send */
} fake_datagram;

typedef struct {
    uint16_t angle;     /* register 0x3FFF, 14 bits */
    uint16_t diag;      /* register 0x3FFD */
    uint16_t magnitude; /* register 0x3FFE */
    int error_flag;     /* sticky until register 0x0001 is read */
    uint16_t error_reg; /* bit 0 framing, bit 1 invalid command, bit 2 parity */
    uint16_t pending;   /* answer to the previous command, sent during the next frame */
    int corrupt_angle;  /* flip one data bit of every angle answer (a parity error) */
    uint16_t log[FAKE_FRAME_LOG]; /* commands received, oldest first */
    unsigned n_log;
} fake_encoder;

typedef struct {
    uint64_t now;           /* microseconds */
    uint64_t send_delay_us; /* the clock moves this much during each send */

    fake_datagram inbox[FAKE_QUEUE];
    unsigned in_head, in_count;
    int receive_error_once; /* next receive returns -1 */

    fake_datagram sent[FAKE_QUEUE]; /* ring of the latest sends */
    unsigned n_sent;                /* total */
    int send_fail;

    int left, right;          /* solenoid outputs */
    unsigned solenoid_calls;
    unsigned energise_calls;  /* calls with either solenoid on */

    fake_encoder enc[4];
    int daisy_chain;          /* expect chip 0, n 4 (else chip 0..3, n 1) */
    int bus_fail;
    unsigned spi_calls;
    unsigned spi_wrong_shape; /* calls that do not fit the configured layout */
    unsigned frames;
    unsigned frames_bad_parity; /* command frames from the core with odd parity */

    int random_fail;
    unsigned random_zero_draws; /* the first N draws return all zeros */
    uint8_t random[8];
    unsigned random_draws; /* draw n returns random[i % 8] + n */

    unsigned kicks;
    int heartbeat_level;      /* as last driven (-1: never) */
    unsigned heartbeat_edges; /* calls that changed the level */
    uint32_t status; /* what sense_status returns */
    int truth_on;
    exo_truth truth;
} fake_board;

void fake_init(fake_board *f);

/* The board interface over `f`; `optional` also fills kick_watchdog, sense_status,
 * heartbeat and truth. */
exo_board fake_interface(fake_board *f, int optional);

/* Queue one datagram for receive (len > sizeof data simulates an oversize one, 0 an
 * empty one). */
void fake_push(fake_board *f, const uint8_t *data, long len, uint32_t ip, uint16_t port);

/* The latest send (NULL if none). */
const fake_datagram *fake_last_sent(const fake_board *f);

/* Even parity over all 16 bits, computed bit by bit (independent of the core's). */
int fake_parity_even(uint16_t frame);

#endif /* EXO_TEST_FAKE_BOARD_H */
