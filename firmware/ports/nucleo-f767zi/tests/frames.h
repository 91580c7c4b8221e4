/*
 * frames.h - hand-assembled reference frames shared by the tests.
 *
 * The checksums (IPv4 0x433e, UDP 0xa08b) were computed outside this code, with a
 * separate one-off script, so they check the implementation rather than restate it.
 */
#ifndef FRAMES_H
#define FRAMES_H

#include <stdint.h>

/* Host 192.168.50.1 port 50000 -> device 192.168.50.2 port 47300, payload
 * "hello, exo!" (11 bytes), IPv4 id 0x1234, don't-fragment, TTL 64. */
#define IPV4_UDP_HELLO                                                                    \
    0x45, 0x00, 0x00, 0x27, 0x12, 0x34, 0x40, 0x00, 0x40, 0x11, 0x43, 0x3e, 192, 168, 50, \
        1, 192, 168, 50, 2, 0xc3, 0x50, 0xb8, 0xc4, 0x00, 0x13, 0xa0, 0x8b, 'h', 'e', 'l', \
        'l', 'o', ',', ' ', 'e', 'x', 'o', '!'

#define DEVICE_MAC 0x02, 0x00, 0x00, 0x00, 0x00, 0x02
#define HOST_MAC 0x02, 0x00, 0x00, 0x00, 0x00, 0x01
#define OTHER_MAC 0x02, 0x00, 0x00, 0x00, 0x00, 0x09

#define IP_DEVICE 0xC0A83202u /* 192.168.50.2 */
#define IP_HOST 0xC0A83201u   /* 192.168.50.1 */
#define IP_OTHER 0xC0A83209u  /* 192.168.50.9 */

#endif /* FRAMES_H */
