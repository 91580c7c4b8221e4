/*
 * emu_prov.h - the emulation provisioning block: EMULATION ONLY.
 *
 * QEMU's mps2-an500 has no flash to keep a key in, no unique id and no random number
 * generator, so whoever starts the emulator writes all three into a 128-byte block and
 * has QEMU put it in memory before reset:
 *
 *     -device loader,file=BLOCK,addr=0x003FF000
 *
 * Layout (multi-byte integers little-endian):
 *
 *   offset size field
 *        0   64 the Nucleo port's provisioning block (prov.h): link key, device IPv4
 *               address, netmask, host IPv4 address, MAC address, UDP port, CRC-32
 *       64    4 magic "EXEM"
 *       68    2 format version, 1
 *       70    2 size of this part, 64
 *       72   16 unique id the device reports in its CHALLENGE (stands in for a
 *               processor's factory id)
 *       88   32 boot seed: 32 random bytes, NEW FOR EVERY BOOT, from which the session
 *               numbers and challenges are drawn (stands in for a hardware RNG)
 *      120    4 reserved, 0
 *      124    4 CRC-32 (IEEE) of bytes 64..123
 *
 * Why this is acceptable only under emulation: on a real board a seed written once
 * would be read again at every reset, so every boot would draw the same session
 * numbers and challenges, and a recorded JOIN of an earlier boot would answer the
 * challenge of a later one; and the key would sit in plain memory that anything
 * loading the block can read. Here the emulator is started by the same user who holds
 * the host's key file, and the launcher (tools/emu_block.py) draws a fresh seed from
 * the host's kernel RNG for every start; the firmware also never resets itself (a
 * reset would re-load the same block), it stops with its outputs off instead.
 */
#ifndef EMU_PROV_H
#define EMU_PROV_H

#include <stddef.h>
#include <stdint.h>

#include "prov.h"

#define EMU_BLOCK_SIZE 128u
#define EMU_EXT_SIZE 64u
#define EMU_VERSION 1u
#define EMU_ID_BYTES 16u
#define EMU_SEED_BYTES 32u

typedef struct {
    prov_block prov;
    uint8_t unique_id[EMU_ID_BYTES];
    uint8_t seed[EMU_SEED_BYTES];
} emu_block;

typedef enum {
    EMU_OK = 0,
    EMU_PROV,     /* the first 64 bytes are no valid provisioning block (see prov_error) */
    EMU_MAGIC,    /* no "EXEM": the loader was not given a block, or at another address */
    EMU_VERSION_BAD,
    EMU_SIZE_BAD,
    EMU_CRC,
    EMU_SEED      /* seed all zero or all 0xFF: no entropy was written */
} emu_error;

/* Check and decode the block at `data`; on EMU_PROV, `*prov_err` says why. */
emu_error emu_parse(const uint8_t *data, size_t len, emu_block *out, prov_error *prov_err);

const char *emu_error_name(emu_error e);

#endif /* EMU_PROV_H */
