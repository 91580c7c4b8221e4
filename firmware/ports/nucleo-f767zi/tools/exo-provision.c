/*
 * exo-provision.c - write (or check) the Nucleo's provisioning block: the link key
 * from the host's key file and the addresses, as the 64 bytes prov.h describes, to be
 * programmed at 0x081C0000 (flash sector 11), apart from the firmware.
 *
 *   exo-provision --key-file var/device.key --device-ip 192.168.50.2 \
 *       --host-ip 192.168.50.1 [--netmask 255.255.255.0] [--mac 02:xx:xx:xx:xx:xx] \
 *       [--port 47300] --out var/nucleo-provision.bin [--image exo-nucleo.bin]
 *   exo-provision --check FILE          decode a block (e.g. read back from the board)
 *
 * --image also writes OUT.full.bin: the firmware padded with 0xFF up to 0x1C0000 and
 * the block after it, one file for tools that only program from 0x08000000 (the
 * Nucleo's drag-and-drop drive). The key file is read with the host's rules (mode
 * 0600, 64 hex digits); outputs are created with mode 0600 since they hold the key.
 */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../prov.h"
#include "sbc_key.h"
#include "sbc_options.h"
#include "sbc_identity.h"

#define PROV_OFFSET 0x1C0000u /* 0x081C0000 - 0x08000000 */

static void die(const char *fmt, const char *arg)
{
    fprintf(stderr, "exo-provision: ");
    fprintf(stderr, fmt, arg);
    fputc('\n', stderr);
    exit(2);
}

static int parse_mac(const char *text, uint8_t mac[6])
{
    unsigned v[6];
    char tail;
    if (sscanf(text, "%2x:%2x:%2x:%2x:%2x:%2x%c", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5],
               &tail) != 6 || strlen(text) != 17) {
        return -1;
    }
    for (int i = 0; i < 6; i++) {
        mac[i] = (uint8_t)v[i];
    }
    return 0;
}

static void write_file(const char *path, const uint8_t *data, size_t len)
{
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0) {
        die("cannot create %s", path);
    }
    if (fchmod(fd, 0600) != 0 || write(fd, data, len) != (ssize_t)len || close(fd) != 0) {
        die("cannot write %s", path);
    }
}

static void print_ip(const char *label, uint32_t ip)
{
    printf("%-12s %u.%u.%u.%u\n", label, ip >> 24, (ip >> 16) & 255u, (ip >> 8) & 255u,
           ip & 255u);
}

static void describe(const prov_block *b)
{
    print_ip("device IP", b->device_ip);
    print_ip("netmask", b->netmask);
    print_ip("host IP", b->host_ip);
    printf("%-12s %02x:%02x:%02x:%02x:%02x:%02x\n", "device MAC", b->mac[0], b->mac[1],
           b->mac[2], b->mac[3], b->mac[4], b->mac[5]);
    printf("%-12s %u\n", "UDP port", (unsigned)b->udp_port);
    /* The same key id the ExoStudy console shows for the host's key file (the first 8
     * bytes of HMAC-SHA256(key, "exostudy key id")): equal ids, equal keys; it reveals
     * nothing usable. */
    char key_id[SBC_KEY_ID_HEX + 1];
    sbc_key_id(b->key, sizeof b->key, key_id);
    printf("%-12s %s (key id; the key itself is not shown)\n", "key", key_id);
}

static int check(const char *path)
{
    uint8_t raw[PROV_SIZE];
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        die("cannot open %s", path);
    }
    size_t n = fread(raw, 1, sizeof raw, f);
    fclose(f);
    prov_block b;
    prov_error e = prov_parse(raw, n, &b);
    if (e != PROV_OK) {
        fprintf(stderr, "exo-provision: %s: %s\n", path, prov_error_name(e));
        return 1;
    }
    describe(&b);
    return 0;
}

int main(int argc, char **argv)
{
    const char *key_file = NULL, *out = NULL, *image = NULL;
    prov_block b;
    memset(&b, 0, sizeof b);
    b.netmask = 0xFFFFFF00u;
    b.udp_port = 47300;
    int have_dev = 0, have_host = 0, have_mac = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0) {
            printf("usage: exo-provision --key-file FILE --device-ip IP --host-ip IP "
                   "[--netmask MASK] [--mac MAC] [--port N] --out FILE [--image FW.bin]\n"
                   "       exo-provision --check FILE\n");
            return 0;
        }
        if (i + 1 >= argc) {
            die("%s needs a value", a);
        }
        const char *v = argv[++i];
        if (strcmp(a, "--check") == 0) {
            return check(v);
        } else if (strcmp(a, "--key-file") == 0) {
            key_file = v;
        } else if (strcmp(a, "--out") == 0) {
            out = v;
        } else if (strcmp(a, "--image") == 0) {
            image = v;
        } else if (strcmp(a, "--device-ip") == 0) {
            if (sbc_parse_ipv4(v, &b.device_ip) != 0) {
                die("--device-ip: '%s' is not an IPv4 address", v);
            }
            have_dev = 1;
        } else if (strcmp(a, "--host-ip") == 0) {
            if (sbc_parse_ipv4(v, &b.host_ip) != 0) {
                die("--host-ip: '%s' is not an IPv4 address", v);
            }
            have_host = 1;
        } else if (strcmp(a, "--netmask") == 0) {
            if (sbc_parse_ipv4(v, &b.netmask) != 0) {
                die("--netmask: '%s' is not a dotted mask", v);
            }
        } else if (strcmp(a, "--mac") == 0) {
            if (parse_mac(v, b.mac) != 0) {
                die("--mac: '%s' is not six hex pairs like 02:45:58:00:00:02", v);
            }
            have_mac = 1;
        } else if (strcmp(a, "--port") == 0) {
            char *end;
            long p = strtol(v, &end, 10);
            if (*end != '\0' || p < 1 || p > 65535) {
                die("--port: '%s' is not 1..65535", v);
            }
            b.udp_port = (uint16_t)p;
        } else {
            die("unknown option '%s'", a);
        }
    }
    if (key_file == NULL || out == NULL || !have_dev || !have_host) {
        die("%s", "--key-file, --device-ip, --host-ip and --out are required (--help)");
    }
    char err[256];
    if (sbc_key_load(key_file, b.key, err, sizeof err) != 0) {
        die("%s", err);
    }
    if (!have_mac) {
        /* A random locally administered unicast address (bit 1 set, bit 0 clear). */
        if (getrandom(b.mac, 6, 0) != 6) {
            die("%s", "no random bytes for a MAC address");
        }
        b.mac[0] = (uint8_t)((b.mac[0] & 0xFCu) | 0x02u);
    }

    uint8_t raw[PROV_SIZE];
    prov_write(&b, raw);
    prov_block back;
    prov_error e = prov_parse(raw, sizeof raw, &back);
    if (e != PROV_OK) {
        die("refused: %s", prov_error_name(e));
    }
    write_file(out, raw, sizeof raw);
    describe(&back);
    printf("wrote %s (64 bytes, mode 0600): program it at 0x081C0000\n", out);

    if (image != NULL) {
        FILE *f = fopen(image, "rb");
        if (f == NULL) {
            die("cannot open %s", image);
        }
        static uint8_t full[PROV_OFFSET + PROV_SIZE];
        memset(full, 0xFF, sizeof full);
        size_t n = fread(full, 1, PROV_OFFSET + 1u, f);
        fclose(f);
        if (n == 0 || n > PROV_OFFSET) {
            die("%s: empty, or larger than the 1792 KB program area", image);
        }
        memcpy(full + PROV_OFFSET, raw, sizeof raw);
        char path[512];
        snprintf(path, sizeof path, "%s.full.bin", out);
        write_file(path, full, sizeof full);
        printf("wrote %s (%u bytes): firmware and block, to program at 0x08000000\n", path,
               (unsigned)sizeof full);
    }
    memset(&b, 0, sizeof b);
    memset(raw, 0, sizeof raw);
    return 0;
}
