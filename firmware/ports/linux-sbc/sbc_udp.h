/*
 * sbc_udp.h - the device's UDP socket: non-blocking, bound to the protocol port.
 */
#ifndef SBC_UDP_H
#define SBC_UDP_H

#include <stddef.h>
#include <stdint.h>

#include "exo_board.h"

int sbc_udp_open(uint32_t bind_ip, uint16_t port, char *err, size_t errlen);
int sbc_udp_send(int fd, const uint8_t *data, size_t len, exo_endpoint to);
/* Length of the next datagram (its true length if longer than `cap`), 0 if none, -1 on
 * error: the board's receive contract. */
long sbc_udp_receive(int fd, uint8_t *buf, size_t cap, exo_endpoint *from);

#endif /* SBC_UDP_H */
