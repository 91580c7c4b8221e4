/* emu_prov.c - read the emulation provisioning block (emu_prov.h). */
#include "emu_prov.h"

#include "crc32.h"

static uint16_t get16(const uint8_t *p)
{
    return (uint16_t)(p[0] | p[1] << 8);
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

emu_error emu_parse(const uint8_t *data, size_t len, emu_block *out, prov_error *prov_err)
{
    *prov_err = PROV_OK;
    if (len < EMU_BLOCK_SIZE) {
        *prov_err = PROV_SHORT;
        return EMU_PROV;
    }
    prov_error perr = prov_parse(data, PROV_SIZE, &out->prov);
    if (perr != PROV_OK) {
        *prov_err = perr;
        return EMU_PROV;
    }
    const uint8_t *ext = data + PROV_SIZE;
    if (ext[0] != 'E' || ext[1] != 'X' || ext[2] != 'E' || ext[3] != 'M') {
        return EMU_MAGIC;
    }
    if (get16(ext + 4) != EMU_VERSION) {
        return EMU_VERSION_BAD;
    }
    if (get16(ext + 6) != EMU_EXT_SIZE) {
        return EMU_SIZE_BAD;
    }
    if (crc32_ieee(ext, EMU_EXT_SIZE - 4u) != get32(ext + EMU_EXT_SIZE - 4u)) {
        return EMU_CRC;
    }
    unsigned zeros = 0, ones = 0;
    for (unsigned i = 0; i < EMU_SEED_BYTES; i++) {
        uint8_t b = ext[24u + i];
        out->seed[i] = b;
        zeros += b == 0x00u;
        ones += b == 0xFFu;
    }
    if (zeros == EMU_SEED_BYTES || ones == EMU_SEED_BYTES) {
        return EMU_SEED;
    }
    for (unsigned i = 0; i < EMU_ID_BYTES; i++) {
        out->unique_id[i] = ext[8u + i];
    }
    return EMU_OK;
}

const char *emu_error_name(emu_error e)
{
    switch (e) {
    case EMU_OK:
        return "ok";
    case EMU_PROV:
        return "no valid provisioning block";
    case EMU_MAGIC:
        return "no emulation block (magic EXEM missing: was -device loader given?)";
    case EMU_VERSION_BAD:
        return "emulation block of another format version";
    case EMU_SIZE_BAD:
        return "emulation block of the wrong size";
    case EMU_CRC:
        return "emulation block damaged (CRC)";
    case EMU_SEED:
        return "emulation block without a boot seed";
    }
    return "unknown";
}
