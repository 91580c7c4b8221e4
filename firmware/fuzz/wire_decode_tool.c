/*
 * wire_decode_tool.c - the core's wire decoder as a line filter, for comparing it with
 * the Python decoder (tests/controller/device/test_decoders_agree.py).
 *
 *   exostudy-wire-decode [--key HEX64] < datagrams
 *
 * Each input line is one datagram in hex (an empty line is an empty datagram); each
 * output line is the verdict: "drop <reason>" with the shared reason name, or the
 * packet type and its fields (sessions in decimal, byte strings in hex):
 *   sample S R t_us=N seq=N status=N counts=A,B,C,D drops=AUTH,REPLAY,STALE truth=-
 *   sample S R ... truth=PROGRESS_BITS_HEX,LIFT,ACTIVITY_HEX  (activity: first 64 bytes)
 *   command S R host_seq=N echo_seq=N locks=N stop_heartbeat=0|1
 *   hello S R host_seq=N
 *   challenge S R hello_seq=N lifetime_ms=N challenge=HEX unique_id=HEX firmware=HEX
 *   join S R host_seq=N challenge=HEX
 *   version lowest=N highest=N
 * The default key is the protocol document's test key (00 01 ... 1f).
 */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "hmac.h"
#include "wire.h"

#define MAX_BYTES 4096

static int hexval(int c)
{
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

/* Parse hex (spaces allowed) into out; returns the byte count or -1. */
static long parse_hex(const char *s, uint8_t *out, size_t cap)
{
    size_t n = 0;
    int hi = -1;
    for (; *s && *s != '\n' && *s != '\r'; s++) {
        if (*s == ' ')
            continue;
        int v = hexval((unsigned char)*s);
        if (v < 0)
            return -1;
        if (hi < 0) {
            hi = v;
        } else {
            if (n == cap)
                return -1;
            out[n++] = (uint8_t)(hi << 4 | v);
            hi = -1;
        }
    }
    return hi < 0 ? (long)n : -1;
}

static void put_hex(const uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; i++)
        printf("%02x", p[i]);
}

static void print_packet(const exo_packet *p)
{
    switch (p->type) {
    case EXO_TYPE_SAMPLE: {
        const exo_sample_fields *s = &p->sample;
        printf("sample %" PRIu64 " %" PRIu64 " t_us=%" PRIu64 " seq=%" PRIu32 " status=%" PRIu32
               " counts=%u,%u,%u,%u drops=%" PRIu32 ",%" PRIu32 ",%" PRIu32 " truth=",
               p->sender, p->receiver, s->t_us, s->seq, s->status, s->counts[0], s->counts[1],
               s->counts[2], s->counts[3], s->auth_drops, s->replay_drops, s->stale_drops);
        if (!s->has_truth) {
            printf("-");
        } else {
            uint64_t bits;
            memcpy(&bits, &s->truth.progress, sizeof bits);
            printf("%016" PRIx64 ",%" PRId32 ",", bits, s->truth.lift_index);
            put_hex((const uint8_t *)s->truth.activity, s->truth.activity_len);
        }
        break;
    }
    case EXO_TYPE_COMMAND:
        printf("command %" PRIu64 " %" PRIu64 " host_seq=%" PRIu32 " echo_seq=%" PRIu32
               " locks=%u stop_heartbeat=%d",
               p->sender, p->receiver, p->host_seq, p->echo_seq, p->locks, p->stop_heartbeat != 0);
        break;
    case EXO_TYPE_HELLO:
        printf("hello %" PRIu64 " %" PRIu64 " host_seq=%" PRIu32, p->sender, p->receiver,
               p->host_seq);
        break;
    case EXO_TYPE_CHALLENGE:
        printf("challenge %" PRIu64 " %" PRIu64 " hello_seq=%" PRIu32 " lifetime_ms=%" PRIu32
               " challenge=",
               p->sender, p->receiver, p->challenge.hello_seq, p->challenge.lifetime_ms);
        put_hex(p->challenge.challenge, sizeof p->challenge.challenge);
        printf(" unique_id=");
        put_hex(p->challenge.unique_id, sizeof p->challenge.unique_id);
        printf(" firmware=");
        size_t fw = 0;
        while (fw < sizeof p->challenge.firmware && p->challenge.firmware[fw] != 0)
            fw++;
        put_hex(p->challenge.firmware, fw);
        break;
    case EXO_TYPE_JOIN:
        printf("join %" PRIu64 " %" PRIu64 " host_seq=%" PRIu32 " challenge=", p->sender,
               p->receiver, p->host_seq);
        put_hex(p->join_challenge, sizeof p->join_challenge);
        break;
    case EXO_TYPE_VERSION:
        printf("version lowest=%u highest=%u", p->lowest, p->highest);
        break;
    default:
        printf("type %u", p->type);
    }
    printf("\n");
}

int main(int argc, char **argv)
{
    uint8_t key[32];
    for (unsigned i = 0; i < 32; i++)
        key[i] = (uint8_t)i;
    if (argc == 3 && strcmp(argv[1], "--key") == 0) {
        if (parse_hex(argv[2], key, sizeof key) != 32) {
            fprintf(stderr, "--key needs 64 hexadecimal digits\n");
            return 2;
        }
    } else if (argc != 1) {
        fprintf(stderr, "usage: %s [--key HEX64] < lines of hex datagrams\n", argv[0]);
        return 2;
    }
    exo_hmac_key k;
    exo_hmac_set_key(&k, key, sizeof key);
    static char line[2 * MAX_BYTES * 2 + 16];
    static uint8_t data[MAX_BYTES];
    unsigned long lineno = 0;
    while (fgets(line, sizeof line, stdin)) {
        lineno++;
        long n = parse_hex(line, data, sizeof data);
        if (n < 0) {
            fprintf(stderr, "line %lu: not hex, or longer than %d bytes\n", lineno, MAX_BYTES);
            return 2;
        }
        exo_packet p;
        memset(&p, 0, sizeof p);
        exo_drop_reason r = exo_wire_decode(&k, data, (size_t)n, &p);
        if (r != EXO_DROP_NONE)
            printf("drop %s\n", exo_drop_reason_name(r));
        else
            print_packet(&p);
    }
    return 0;
}
