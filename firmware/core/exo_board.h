/*
 * exo_board.h - what a board gives the portable device core.
 *
 * The core (protocol, authentication, sessions, watchdog, encoder framing) never
 * touches hardware. A port fills one `exo_board` with function pointers and a context
 * pointer; the core calls nothing else. Keeping the interface this small is what lets
 * the same core run on a microcontroller, on a Linux board and against the simulated
 * wearer, and be tested on a desktop with the sanitizers.
 *
 * Every function is called from one thread (the port's main loop); none may block for
 * longer than a fraction of the 10 ms sample period.
 */
#ifndef EXO_BOARD_H
#define EXO_BOARD_H

#include <stddef.h>
#include <stdint.h>

/* exo_board.receive: no datagram is waiting (0 is an empty datagram, -1 an error). */
#define EXO_RX_NONE (-2L)

/* An IPv4 address and UDP port, host byte order (192.168.1.2 is 0xC0A80102). */
typedef struct {
    uint32_t ip;
    uint16_t port;
} exo_endpoint;

/* Ground truth of a simulated wearer (simulator ports only; real boards leave
 * `truth` NULL and the core never sends the extension). */
typedef struct {
    double progress;       /* 0..1 through the current lift, NaN if none */
    int32_t lift_index;    /* -1 if none */
    uint8_t activity_len;  /* 0..64 */
    char activity[64];     /* UTF-8, no terminator needed */
} exo_truth;

typedef struct {
    void *ctx; /* passed back to every call */

    /* Monotonic microseconds since an arbitrary origin; never goes back. */
    uint64_t (*now_us)(void *ctx);

    /* Clock `n` 16-bit frames through the encoder bus (AS5048A: SPI mode 1, MSB
     * first). `tx[i]` goes out while `rx[i]` comes in.
     * - One chip select per encoder: `chip` is 0..3 (left output, left cam, right
     *   output, right cam) and `n` is 1; chip select low for the frame, high after it.
     * - Daisy chain: `chip` is 0 and `n` is 4, one chip select held low for all 64
     *   bits; `tx[i]` is the command for encoder i and `rx[i]` must be encoder i's
     *   answer (the port orders the frames to match its wiring).
     * The bus is pipelined: each answer is the reply to the previous frame's command
     * for that encoder. Per sample the core sends, per encoder, 0x7FFD (read
     * diagnostics), 0xFFFF (read angle), 0x0000 (NOP), preceded by 0x4001 (read and
     * clear the error flag) after a fault; see as5048a.h. Returns 0, or -1 if the bus
     * failed (the core then reports ENCODER_FAULT). */
    int (*spi_transfer)(void *ctx, unsigned chip, const uint16_t *tx, uint16_t *rx, size_t n);

    /* Energise (1) or release (0) each solenoid. Called at init and stop (0, 0) and
     * once per sample while samples stream, with the state the watchdog allows, before
     * the encoders are read (a simulator port may advance its wearer here). A JOIN's
     * release takes effect at the next sample period's call, like any command. */
    void (*set_solenoids)(void *ctx, int left, int right);

    /* Send one datagram to `to`. Returns 0, or -1 if it could not be sent (counted,
     * never retried: the next sample supersedes it). */
    int (*send)(void *ctx, const uint8_t *data, size_t len, exo_endpoint to);

    /* Take one received datagram if there is one, without blocking. Returns its
     * length (0 for an EMPTY datagram, which the core reads and counts as `short`:
     * every datagram is counted, a flood of empty ones included), EXO_RX_NONE if none
     * is waiting, -1 on an error; fills `from` for every datagram. For a datagram
     * longer than `cap` the port returns a value above `cap` (its true length) and the
     * core counts it as malformed ("length") without reading `buf`. A port may instead
     * truncate to `cap` bytes: the core's buffer is one byte longer than the largest
     * packet, so a truncated datagram still fails the length check. */
    long (*receive)(void *ctx, uint8_t *buf, size_t cap, exo_endpoint *from);

    /* Fill `out` with `n` random bytes for session numbers (a hardware RNG, or
     * getrandom). Returns 0, or -1 if no entropy is available (the core then refuses
     * to start: a predictable session would make replays possible). */
    int (*random_bytes)(void *ctx, uint8_t *out, size_t n);

    /* Optional (NULL if absent): kick the board's hardware watchdog. Called once per
     * sample period while the loop runs, so a hung loop resets the board, and a reset
     * board boots with its solenoids off. */
    void (*kick_watchdog)(void *ctx);

    /* Optional (NULL if absent): mechanism, supply and driver status bits the board
     * can sense (LOCKED_*, HARD_STOP_*, SUPPLY_FAULT, and DRIVERS_OFF if it reads the
     * solenoid drivers' enable line back and finds it off). The core sets the
     * SOLENOID_*, ENCODER_FAULT, WATCHDOG_RELEASED and HEARTBEAT_STOPPED bits itself;
     * any other bit is ignored. */
    uint32_t (*sense_status)(void *ctx);

    /* Optional (NULL if the board has no heartbeat pin): drive the heartbeat output
     * to `level` (0 or 1). The core toggles it once per sample period while streaming
     * and once per idle period before, unless the latest applied COMMAND carried
     * STOP_HEARTBEAT (a bring-up probe). An external retriggerable monostable holds
     * the solenoid drivers' enable for 30 ms after each edge, so a firmware that stops
     * running releases the solenoids without the firmware's help. */
    void (*heartbeat)(void *ctx, int level);

    /* Optional (NULL on real hardware): the simulated wearer's ground truth for the
     * sample being built. Returns 1 if `out` was filled. */
    int (*truth)(void *ctx, exo_truth *out);
} exo_board;

#endif /* EXO_BOARD_H */
