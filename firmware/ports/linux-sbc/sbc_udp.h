/*
 * sbc_udp.h - the device's UDP socket: non-blocking, bound to the protocol port.
 *
 * Every datagram is counted and the backlog is capped (issue: a flood of empty
 * datagrams went uncounted):
 *   - an EMPTY datagram is returned as length 0, which the core reads and counts as
 *     `short`; "nothing waiting" is EXO_RX_NONE, a different value, so an empty
 *     datagram can never stop the core from draining the socket;
 *   - the socket's receive buffer is capped (SBC_UDP_RCVBUF), so a flood can keep at
 *     most a few dozen datagrams ahead of the host's next command, and the core's
 *     per-period authentication budget bounds the work per datagram;
 *   - datagrams the kernel drops because that buffer is full are counted too: the
 *     socket asks for SO_RXQ_OVFL, the kernel's count of them, with every datagram.
 * So datagrams sent to the port = `received` + `kernel_drops` (tests/test_sbc.c).
 */
#ifndef SBC_UDP_H
#define SBC_UDP_H

#include <stddef.h>
#include <stdint.h>

#include "exo_board.h"

#define SBC_UDP_RCVBUF 32768 /* bytes asked for; Linux doubles it for its bookkeeping */

typedef struct {
    int fd;
    uint64_t received;      /* datagrams read, empty ones included */
    uint64_t empty;         /* of which empty */
    uint32_t kernel_drops;  /* dropped by the kernel, buffer full (SO_RXQ_OVFL) */
    uint64_t errors;        /* recvmsg failed other than "nothing waiting" */
} sbc_udp;

/* Open and bind. 0, or -1 with the reason in `err` (u->fd is then -1). */
int sbc_udp_open(sbc_udp *u, uint32_t bind_ip, uint16_t port, char *err, size_t errlen);
int sbc_udp_send(sbc_udp *u, const uint8_t *data, size_t len, exo_endpoint to);
/* The board's receive contract: the next datagram's length (its true length if longer
 * than `cap`; 0 if empty), EXO_RX_NONE if none is waiting, -1 on an error. */
long sbc_udp_receive(sbc_udp *u, uint8_t *buf, size_t cap, exo_endpoint *from);
void sbc_udp_close(sbc_udp *u);

#endif /* SBC_UDP_H */
