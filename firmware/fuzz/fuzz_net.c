/*
 * fuzz_net.c - libFuzzer harness for the Nucleo-F767ZI network stack
 * (ports/nucleo-f767zi/net): a program of received Ethernet frames, receives, sends
 * and clock steps, decoded from the input.
 *
 * Frames are either raw bytes or built by the harness from chosen fields (addresses,
 * ports, checksums right or wrong, fragments, padding), so that the fuzzer reaches the
 * UDP queue as easily as the parsers' error paths. After every step:
 * - the receive queue holds exactly what an independent reading of the frames (below,
 *   not the stack's parsers) says it should, in order, byte for byte;
 * - the stack drops datagrams from sources other than the host before queueing (its
 *   flood rule): no other source is ever queued, and pings from elsewhere go
 *   unanswered;
 * - every frame the stack sends is 60..1514 bytes from the device's MAC, with valid
 *   IPv4 and UDP checksums, UDP only to the host at its learned MAC;
 * - the learned host MAC is never a multicast address.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "net_stack.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define DEV_IP 0xC0A8FA02u  /* 192.168.250.2 */
#define HOST_IP 0xC0A8FA01u /* 192.168.250.1 */
#define OTHER_IP 0xC0A8FA07u
#define PORT 47300u
#define SHADOW 64

static const uint8_t DEV_MAC[6] = {0x02, 0x00, 0x00, 0x00, 0x00, 0x02};
static const uint8_t HOST_MAC[6] = {0x02, 0x00, 0x00, 0x00, 0x00, 0x01};
static const uint8_t OTHER_MAC[6] = {0x02, 0x00, 0x00, 0x00, 0x00, 0x07};
static const uint8_t MCAST_MAC[6] = {0x01, 0x00, 0x5e, 0x00, 0x00, 0x01};
static const uint8_t BCAST_MAC[6] = {0xff, 0xff, 0xff, 0xff, 0xff, 0xff};

typedef struct {
    uint32_t ip;
    uint16_t port;
    uint16_t len;
    uint8_t data[NET_UDP_MAX];
} expect_dgram;

static net_stack stack;
static expect_dgram shadow[SHADOW];
static unsigned sh_head, sh_count;
static int host_only; /* the stack must drop non-host sources before queueing */
static int in_input;  /* sends during net_stack_input are answers (ARP, ping) */
static uint64_t now;

/* The input, read front to back; zeros once it runs out. */
typedef struct {
    const uint8_t *p;
    size_t n;
} reader;

static unsigned u8(reader *r)
{
    if (r->n == 0)
        return 0;
    r->n--;
    return *r->p++;
}

static unsigned u16(reader *r) { return u8(r) | u8(r) << 8; }

static uint32_t u32(reader *r) { return (uint32_t)u16(r) | (uint32_t)u16(r) << 16; }

static void fail(const char *why, const uint8_t *frame, size_t len)
{
    fprintf(stderr, "net invariant: %s\n", why);
    if (frame) {
        fprintf(stderr, "frame (%zu bytes):", len);
        for (size_t i = 0; i < len; i++)
            fprintf(stderr, " %02x", frame[i]);
        fprintf(stderr, "\n");
    }
    abort();
}

static unsigned get16(const uint8_t *p) { return (unsigned)p[0] << 8 | p[1]; }

static uint32_t get32(const uint8_t *p) { return (uint32_t)get16(p) << 16 | get16(p + 2); }

static void put16(uint8_t *p, unsigned v)
{
    p[0] = (uint8_t)(v >> 8);
    p[1] = (uint8_t)v;
}

static void put32(uint8_t *p, uint32_t v)
{
    put16(p, v >> 16);
    put16(p + 2, v & 0xFFFFu);
}

/* RFC 1071 one's-complement sum of 16-bit words (odd byte padded with zero). */
static uint32_t ones_sum(uint32_t acc, const uint8_t *p, size_t n)
{
    for (size_t i = 0; i + 1 < n; i += 2)
        acc += get16(p + i);
    if (n & 1u)
        acc += (uint32_t)p[n - 1] << 8;
    return acc;
}

static unsigned fold(uint32_t acc)
{
    while (acc >> 16)
        acc = (acc & 0xFFFFu) + (acc >> 16);
    return acc;
}

static uint32_t pseudo(uint32_t src, uint32_t dst, size_t ulen)
{
    uint8_t ph[12];
    put32(ph, src);
    put32(ph + 4, dst);
    ph[8] = 0;
    ph[9] = 17;
    put16(ph + 10, (unsigned)ulen);
    return ones_sum(0, ph, sizeof ph);
}

/* The harness's own reading of a received frame: 1 if a UDP datagram for the device
 * is in it (filled into `e`), else 0. Written from RFC 791/768/894, not from net/. */
static int frame_datagram(const uint8_t *f, size_t len, expect_dgram *e)
{
    if (len < 14 || len > 1514)
        return 0;
    if (memcmp(f, DEV_MAC, 6) != 0 && memcmp(f, BCAST_MAC, 6) != 0)
        return 0;
    if (get16(f + 12) != 0x0800)
        return 0;
    const uint8_t *ip = f + 14;
    size_t avail = len - 14;
    if (avail < 20 || ip[0] >> 4 != 4)
        return 0;
    size_t ihl = (size_t)(ip[0] & 15u) * 4u, total = get16(ip + 2);
    if (ihl < 20 || ihl > avail || total < ihl || total > avail)
        return 0;
    if (fold(ones_sum(0, ip, ihl)) != 0xFFFFu)
        return 0;
    if (get16(ip + 6) & 0x3FFFu)
        return 0; /* a fragment (more-fragments or an offset) */
    if (get32(ip + 16) != DEV_IP || ip[9] != 17)
        return 0;
    const uint8_t *u = ip + ihl;
    size_t plen = total - ihl;
    if (plen < 8)
        return 0;
    size_t ulen = get16(u + 4);
    if (ulen < 8 || ulen > plen)
        return 0;
    uint32_t src = get32(ip + 12);
    if (get16(u + 6) != 0 && fold(ones_sum(pseudo(src, DEV_IP, ulen), u, ulen)) != 0xFFFFu)
        return 0;
    if (ulen == 8 || get16(u + 2) != PORT)
        return 0;
    if (host_only && src != HOST_IP)
        return 0;
    e->ip = src;
    e->port = (uint16_t)get16(u);
    e->len = (uint16_t)(ulen - 8);
    memcpy(e->data, u + 8, ulen - 8);
    return 1;
}

static void check_sent(const uint8_t *f, size_t len)
{
    if (len < 60 || len > 1514)
        fail("sent frame size outside 60..1514", f, len);
    if (memcmp(f + 6, DEV_MAC, 6) != 0)
        fail("sent frame not from the device's MAC", f, len);
    unsigned type = get16(f + 12);
    if (type == 0x0806) {
        if (len < 14 + 28 || get32(f + 14 + 14) != DEV_IP)
            fail("ARP sent with a sender address other than the device's", f, len);
        return;
    }
    if (type != 0x0800)
        fail("sent frame neither ARP nor IPv4", f, len);
    const uint8_t *ip = f + 14;
    size_t total = get16(ip + 2);
    if ((ip[0] & 15u) != 5 || total < 20 || total > len - 14)
        fail("sent IPv4 header malformed", f, len);
    if (fold(ones_sum(0, ip, 20)) != 0xFFFFu)
        fail("sent IPv4 header checksum wrong", f, len);
    if (get32(ip + 12) != DEV_IP)
        fail("sent IPv4 source is not the device", f, len);
    if (ip[9] == 17) {
        if (in_input)
            fail("UDP sent while handling a received frame", f, len);
        if (get32(ip + 16) != HOST_IP || !stack.peer_mac_known ||
            memcmp(f, stack.peer_mac, 6) != 0)
            fail("UDP sent to someone other than the host at its learned MAC", f, len);
        const uint8_t *u = ip + 20;
        size_t ulen = get16(u + 4);
        if (ulen != total - 20 || get16(u) != PORT)
            fail("sent UDP header wrong", f, len);
        if (get16(u + 6) == 0 || fold(ones_sum(pseudo(DEV_IP, HOST_IP, ulen), u, ulen)) != 0xFFFFu)
            fail("sent UDP checksum wrong", f, len);
    } else if (ip[9] == 1) {
        if (!in_input)
            fail("ICMP sent unprompted", f, len);
        if (host_only && get32(ip + 16) != HOST_IP)
            fail("ping answered to a source other than the host", f, len);
    } else {
        fail("sent IPv4 of another protocol", f, len);
    }
}

static int link_send(void *ctx, const uint8_t *frame, size_t len)
{
    int *refuse = ctx;
    check_sent(frame, len);
    return *refuse ? -1 : 0;
}

static void check_queue(void)
{
    if (stack.rx_count > NET_RXQ_LEN || stack.rx_head >= NET_RXQ_LEN)
        fail("receive queue indices out of range", NULL, 0);
    if (stack.rx_count != sh_count)
        fail("receive queue holds a different number of datagrams than the frames carried", NULL, 0);
    for (unsigned i = 0; i < stack.rx_count; i++) {
        const net_datagram *d = &stack.rxq[(stack.rx_head + i) % NET_RXQ_LEN];
        if (d->len == 0 || d->len > NET_UDP_MAX)
            fail("queued datagram of impossible length", NULL, 0);
        if (host_only && d->src_ip != HOST_IP)
            fail("a datagram from a source other than the host was queued", NULL, 0);
    }
    if (stack.peer_mac_known && (stack.peer_mac[0] & 1u))
        fail("learned host MAC is a multicast address", NULL, 0);
}

static void input(const uint8_t *f, size_t len)
{
    expect_dgram e;
    int carries = frame_datagram(f, len, &e);
    in_input = 1;
    net_stack_input(&stack, f, len, now);
    in_input = 0;
    if (carries && sh_count < NET_RXQ_LEN) {
        shadow[(sh_head + sh_count) % SHADOW] = e;
        sh_count++;
    }
    check_queue();
}

static const uint8_t *pick_mac(unsigned c)
{
    switch (c % 5u) {
    case 0: return DEV_MAC;
    case 1: return HOST_MAC;
    case 2: return OTHER_MAC;
    case 3: return BCAST_MAC;
    default: return MCAST_MAC;
    }
}

static uint32_t pick_ip(unsigned c, reader *r)
{
    switch (c % 4u) {
    case 0: return HOST_IP;
    case 1: return DEV_IP;
    case 2: return OTHER_IP;
    default: return u32(r);
    }
}

/* A UDP (or, with `icmp`, ICMP echo) frame built from chosen fields. */
static size_t build_ip_frame(uint8_t *f, reader *r, int icmp)
{
    unsigned c = u8(r), c2 = u8(r);
    memcpy(f, (c & 1u) ? BCAST_MAC : DEV_MAC, 6);
    if (c & 2u)
        memcpy(f, pick_mac(u8(r)), 6);
    memcpy(f + 6, pick_mac(1 + ((c >> 2) & 3u)), 6);
    put16(f + 12, 0x0800);
    uint32_t src = pick_ip(c >> 4, r), dst = (c & 0x40u) ? pick_ip(u8(r), r) : DEV_IP;
    size_t plen = u16(r) % 300u;
    size_t opts = (c2 & 3u) * 4u;
    uint8_t *ip = f + 14, *u = ip + 20 + opts;
    size_t l4 = (icmp ? 8u : 8u) + plen;
    ip[0] = (uint8_t)(0x40u | (5u + opts / 4u));
    ip[1] = 0;
    put16(ip + 2, (unsigned)(20 + opts + l4));
    put16(ip + 4, u16(r));
    put16(ip + 6, (c2 & 4u) ? (u16(r) & 0xBFFFu) : 0x4000u);
    ip[8] = 64;
    ip[9] = icmp ? 1 : 17;
    put16(ip + 10, 0);
    put32(ip + 12, src);
    put32(ip + 16, dst);
    memset(ip + 20, 1, opts); /* NOP options */
    for (size_t i = 0; i < plen; i++)
        u[8 + i] = (uint8_t)u8(r);
    if (icmp) {
        u[0] = (c2 & 8u) ? (uint8_t)u8(r) : 8u; /* echo request */
        u[1] = 0;
        put16(u + 2, 0);
        put16(u + 4, u16(r));
        put16(u + 6, u16(r));
        put16(u + 2, fold(ones_sum(0, u, l4)) ^ 0xFFFFu);
    } else {
        put16(u, u16(r));
        put16(u + 2, (c2 & 8u) ? u16(r) : PORT);
        put16(u + 4, (unsigned)l4);
        put16(u + 6, 0);
        if (!(c2 & 16u)) {
            unsigned s = fold(ones_sum(pseudo(src, dst, l4), u, l4)) ^ 0xFFFFu;
            put16(u + 6, s == 0 ? 0xFFFFu : s);
        }
        if (c2 & 32u)
            put16(u + 4, u16(r)); /* a lying UDP length */
    }
    put16(ip + 10, fold(ones_sum(0, ip, 20 + opts)) ^ 0xFFFFu);
    size_t len = 14 + 20 + opts + l4;
    while (len < 60)
        f[len++] = 0; /* Ethernet padding */
    if (c2 & 64u)
        len += u8(r) % 32u; /* trailing bytes beyond the IP total length */
    if (c2 & 128u) {
        size_t at = u16(r) % len;
        f[at] ^= (uint8_t)(1u + u8(r) % 255u); /* one damaged byte */
    }
    return len;
}

static size_t build_arp(uint8_t *f, reader *r)
{
    unsigned c = u8(r);
    memcpy(f, (c & 1u) ? DEV_MAC : BCAST_MAC, 6);
    const uint8_t *sha = pick_mac(1 + ((c >> 1) & 3u));
    memcpy(f + 6, sha, 6);
    put16(f + 12, 0x0806);
    uint8_t *a = f + 14;
    put16(a, 1);
    put16(a + 2, 0x0800);
    a[4] = 6;
    a[5] = 4;
    put16(a + 6, (c & 8u) ? 2u : 1u);
    memcpy(a + 8, sha, 6);
    put32(a + 14, pick_ip(c >> 4, r));
    memset(a + 18, 0, 6);
    put32(a + 24, (c & 64u) ? pick_ip(u8(r), r) : DEV_IP);
    size_t len = 60;
    memset(f + 42, 0, len - 42);
    if (c & 128u)
        a[u8(r) % 28u] = (uint8_t)u8(r);
    return len;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static uint8_t frame[NET_ETH_MAX + 64];
    static uint8_t buf[NET_UDP_MAX + 8];
    int refuse = 0;
    net_config cfg;
    memset(&cfg, 0, sizeof cfg);
    memcpy(cfg.mac, DEV_MAC, 6);
    cfg.ip = DEV_IP;
    cfg.netmask = 0xFFFFFF00u;
    cfg.udp_port = PORT;
    cfg.peer_ip = HOST_IP;

    /* Probe: a well-formed datagram from another source must not be queued. */
    net_stack_init(&stack, &cfg, link_send, &refuse);
    sh_head = sh_count = 0;
    host_only = 1;
    now = 0;
    {
        /* from OTHER_IP, three payload bytes, checksums right, to the device's port */
        static const uint8_t probe_prog[] = {0x20, 0x00, 0x03, 0x00, 0x01, 0x00,
                                             'x',  'y',  'z',  0x34, 0x12};
        reader pr = {probe_prog, sizeof probe_prog};
        size_t n = build_ip_frame(frame, &pr, 0); /* from OTHER_IP to the port */
        in_input = 1;
        net_stack_input(&stack, frame, n, 0);
        in_input = 0;
        if (stack.rx_count != 0)
            fail("a datagram from a source other than the host was queued", frame, n);
    }
    net_stack_init(&stack, &cfg, link_send, &refuse);

    reader r = {data, size};
    unsigned steps = 0;
    while (r.n > 0 && steps++ < 64) {
        unsigned op = u8(&r);
        switch (op % 8u) {
        case 0: { /* raw frame */
            size_t len = u16(&r) % (NET_ETH_MAX + 8u);
            if (len > r.n)
                len = r.n;
            memcpy(frame, r.p, len);
            r.p += len;
            r.n -= len;
            input(frame, len);
            break;
        }
        case 1:
        case 2:
            input(frame, build_ip_frame(frame, &r, 0));
            break;
        case 3:
            input(frame, build_ip_frame(frame, &r, 1));
            break;
        case 4:
            input(frame, build_arp(frame, &r));
            break;
        case 5: { /* the core takes a datagram */
            size_t cap = (op & 0x80u) ? u16(&r) % sizeof buf : sizeof buf;
            uint32_t ip = 0;
            uint16_t port = 0;
            long got = net_stack_receive(&stack, buf, cap, &ip, &port);
            if (sh_count == 0) {
                if (got != 0)
                    fail("receive returned a datagram from an empty queue", NULL, 0);
                break;
            }
            expect_dgram *e = &shadow[sh_head];
            sh_head = (sh_head + 1u) % SHADOW;
            sh_count--;
            if (got != (long)e->len || ip != e->ip || port != e->port)
                fail("received datagram differs from the frame that carried it", NULL, 0);
            if ((size_t)got <= cap && memcmp(buf, e->data, e->len) != 0)
                fail("received datagram bytes differ from the frame's", NULL, 0);
            check_queue();
            break;
        }
        case 6: { /* the core sends a datagram */
            size_t len = u16(&r) % (NET_UDP_MAX + 4u);
            uint32_t dst = (op & 0x80u) ? pick_ip(u8(&r), &r) : HOST_IP;
            refuse = (op & 0x40u) != 0;
            memset(buf, 0x5a, len < sizeof buf ? len : sizeof buf);
            int rc = net_stack_send_udp(&stack, dst, (uint16_t)u16(&r), buf,
                                        len < sizeof buf ? len : sizeof buf, now);
            if (rc == 0 && (dst != HOST_IP || !stack.peer_mac_known || len > NET_UDP_MAX))
                fail("send_udp succeeded to a destination it cannot have", NULL, 0);
            refuse = 0;
            check_queue();
            break;
        }
        default: /* the clock moves */
            now += (uint64_t)u16(&r) * ((op & 0x80u) ? 1000u : 10u);
            break;
        }
    }
    return 0;
}
