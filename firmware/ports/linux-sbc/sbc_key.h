/*
 * sbc_key.h - read the link key file the host writes (var/device.key): 64 hexadecimal
 * digits, optionally surrounded by whitespace (the host writes a trailing newline), in
 * a file only its owner may read, as the host itself demands
 * (controller.device.auth.load_key).
 */
#ifndef SBC_KEY_H
#define SBC_KEY_H

#include <stddef.h>
#include <stdint.h>

#define SBC_KEY_BYTES 32

/* Decode `len` bytes of key file text. 0 on success; -1 with a reason in `err`. */
int sbc_key_parse(const char *text, size_t len, uint8_t key[SBC_KEY_BYTES], char *err,
                  size_t errlen);

/* Open, check the mode (no group or other permission bits) and decode `path`. */
int sbc_key_load(const char *path, uint8_t key[SBC_KEY_BYTES], char *err, size_t errlen);

#endif /* SBC_KEY_H */
