/*
 * crc32.h - CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320) of a byte block.
 *
 * Guards the provisioning block in flash against a partial write or a wrong address;
 * it is not a security measure (the key's secrecy is).
 */
#ifndef CRC32_H
#define CRC32_H

#include <stddef.h>
#include <stdint.h>

uint32_t crc32_ieee(const uint8_t *data, size_t len);

#endif /* CRC32_H */
