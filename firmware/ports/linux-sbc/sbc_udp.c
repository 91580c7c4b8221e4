/* sbc_udp.c - UDP socket calls for the board interface. */
#include "sbc_udp.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

int sbc_udp_open(uint32_t bind_ip, uint16_t port, char *err, size_t errlen)
{
    int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) {
        snprintf(err, errlen, "socket: %s", strerror(errno));
        return -1;
    }
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(port);
    a.sin_addr.s_addr = htonl(bind_ip);
    if (bind(fd, (struct sockaddr *)&a, sizeof a) < 0) {
        snprintf(err, errlen, "bind to port %u: %s", (unsigned)port, strerror(errno));
        close(fd);
        return -1;
    }
    return fd;
}

int sbc_udp_send(int fd, const uint8_t *data, size_t len, exo_endpoint to)
{
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons(to.port);
    a.sin_addr.s_addr = htonl(to.ip);
    ssize_t n = sendto(fd, data, len, MSG_DONTWAIT, (struct sockaddr *)&a, sizeof a);
    return n == (ssize_t)len ? 0 : -1;
}

long sbc_udp_receive(int fd, uint8_t *buf, size_t cap, exo_endpoint *from)
{
    struct sockaddr_in a;
    socklen_t alen = sizeof a;
    /* MSG_TRUNC: the return value is the datagram's true length even if cut. */
    ssize_t n = recvfrom(fd, buf, cap, MSG_DONTWAIT | MSG_TRUNC, (struct sockaddr *)&a, &alen);
    if (n < 0) {
        return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -1;
    }
    if (n == 0) {
        /* An empty datagram: report a 1-byte "datagram" the core drops as short,
         * rather than 0, which would mean "nothing waiting" and stop the drain. */
        buf[0] = 0;
        n = 1;
    }
    from->ip = ntohl(a.sin_addr.s_addr);
    from->port = ntohs(a.sin_port);
    return (long)n;
}
