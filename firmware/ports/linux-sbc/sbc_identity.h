/*
 * sbc_identity.h - what exo-sbc tells the host about itself in its CHALLENGEs (the
 * device identity hardware profiles are bound to), and the key id it prints.
 *
 * unique_id, 16 bytes, from one of two sources, named in the banner:
 *   - `--device-id HEX`: a serial number the lab assigns (1..32 hex digits; an odd
 *     count gets a leading 0; the bytes come first and are zero-padded to 16, as the
 *     CHALLENGE pads every id);
 *   - otherwise /etc/machine-id (systemd's 128-bit id of the installed system). It is
 *     not sent as it is (machine-id(5) asks programs to treat it as confidential and to
 *     send only a keyed hash of it): unique_id = the first 16 bytes of
 *     HMAC-SHA256(key = the 16 machine-id bytes, "exo-sbc unique id"). Reinstalling the
 *     operating system gives a new machine-id, so a new identity (bring-up again).
 */
#ifndef SBC_IDENTITY_H
#define SBC_IDENTITY_H

#include <stddef.h>
#include <stdint.h>

#define SBC_UNIQUE_ID_BYTES 16
#define SBC_KEY_ID_HEX 16 /* 8 bytes as lowercase hex */
#define SBC_FIRMWARE_NAME "exo-sbc 3"
#define SBC_MACHINE_ID_PATH "/etc/machine-id"

/* "--device-id" text to 16 bytes. 0, or -1 if empty, longer than 32 digits or not hex. */
int sbc_parse_device_id(const char *hex, uint8_t out[SBC_UNIQUE_ID_BYTES]);

/* machine-id file contents (32 hex digits and a newline) to its 16 bytes. 0, or -1. */
int sbc_parse_machine_id(const char *text, size_t len, uint8_t out[SBC_UNIQUE_ID_BYTES]);

/* The unique id sent for a machine-id (the keyed hash above). */
void sbc_unique_id_from_machine_id(const uint8_t machine_id[SBC_UNIQUE_ID_BYTES],
                                   uint8_t out[SBC_UNIQUE_ID_BYTES]);

/* Read `path` (normally /etc/machine-id) and derive the unique id. 0, or -1 with the
 * reason in `err`. */
int sbc_unique_id_load(const char *path, uint8_t out[SBC_UNIQUE_ID_BYTES], char *err,
                       size_t errlen);

/* The key id the host's console shows: the first 8 bytes of HMAC-SHA256(key,
 * "exostudy key id") as 16 lowercase hex digits and a NUL. */
void sbc_key_id(const uint8_t *key, size_t key_len, char out[SBC_KEY_ID_HEX + 1]);

#endif /* SBC_IDENTITY_H */
