/* sbc_udp.c - UDP socket calls for the board interface (sbc_udp.h). */
#include "sbc_udp.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

int sbc_udp_open(sbc_udp *u, uint32_t bind_ip, uint16_t port, char *err, size_t errlen)
{
    memset(u, 0, sizeof *u);
    u->fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (u->fd < 0) {
        snprintf(err, errlen, "socket: %s", strerror(errno));
        return -1;
    }
    int on = 1, rcvbuf = SBC_UDP_RCVBUF;
    if (setsockopt(u->fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0 ||
        setsockopt(u->fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf) != 0) {
        snprintf(err, errlen, "socket options: %s", strerror(errno));
        sbc_udp_close(u);
        return -1;
    }
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    a.sin_addr.s_addr = htonl(bind_ip);
    if (bind(u->fd, (struct sockaddr *)&a, sizeof a) < 0) {
        snprintf(err, errlen, "bind to port %u: %s", (unsigned)port, strerror(errno));
        sbc_udp_close(u);
        return -1;
    }
    return 0;
}

int sbc_udp_send(sbc_udp *u, const uint8_t *data, size_t len, exo_endpoint to)
{
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(to.port);
    a.sin_addr.s_addr = htonl(to.ip);
    ssize_t n = sendto(u->fd, data, len, MSG_DONTWAIT, (struct sockaddr *)&a, sizeof a);
    return n == (ssize_t)len ? 0 : -1;
}

long sbc_udp_receive(sbc_udp *u, uint8_t *buf, size_t cap, exo_endpoint *from)
{
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    struct iovec iov = {buf, cap};
    union {
        struct cmsghdr align;
        uint8_t bytes[CMSG_SPACE(sizeof(uint32_t))];
    } control;
    struct msghdr m;
    memset(&m, 0, sizeof m);
    m.msg_name = &a;
    m.msg_namelen = sizeof a;
    m.msg_iov = &iov;
    m.msg_iovlen = 1;
    m.msg_control = control.bytes;
    m.msg_controllen = sizeof control.bytes;
    /* MSG_TRUNC: the return value is the datagram's true length even if cut. */
    ssize_t n = recvmsg(u->fd, &m, MSG_DONTWAIT | MSG_TRUNC);
    if (n < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) {
            return EXO_RX_NONE;
        }
        u->errors++;
        return -1;
    }
    for (struct cmsghdr *c = CMSG_FIRSTHDR(&m); c != NULL; c = CMSG_NXTHDR(&m, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
            memcpy(&u->kernel_drops, CMSG_DATA(c), sizeof u->kernel_drops);
        }
    }
    u->received++;
    if (n == 0) {
        u->empty++; /* length 0: the core counts it as `short` */
    }
    from->ip = ntohl(a.sin_addr.s_addr);
    from->port = ntohs(a.sin_port);
    return (long)n;
}

void sbc_udp_close(sbc_udp *u)
{
    if (u->fd >= 0) {
        close(u->fd);
    }
    u->fd = -1;
}
