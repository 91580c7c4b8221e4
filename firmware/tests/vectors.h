/*
 * vectors.h - the eight test datagrams of docs/device-protocol.md ("Test vectors"),
 * copied byte for byte. Key 00 01 .. 1f, device session 0x1122334455667788, host
 * session 0x0123456789abcdef; together one exchange: HELLO 5, its CHALLENGE, JOIN 6,
 * a SAMPLE, COMMAND 7 answering it, COMMAND 8; and a VERSION packet.
 */
#ifndef EXO_TEST_VECTORS_H
#define EXO_TEST_VECTORS_H

#define VEC_DEVICE_SESSION 0x1122334455667788u
#define VEC_HOST_SESSION 0x0123456789abcdefu

/* SAMPLE, seq 258, t 2.58 s, counts (3100, 3105, 12900, 12890), status 0x005, device
 * dropped 1 datagram for a failed tag, 2 as replays, 3 as stale; 92 bytes. */
static const char *const VEC_SAMPLE =
    "45 58 03 01 24 00 00 00 20 5e 27 00 00 00 00 00 02 01 00 00 05 00 00 00 "
    "1c 0c 21 0c 64 32 5a 32 01 00 00 00 02 00 00 00 03 00 00 00 88 77 66 55 "
    "44 33 22 11 ef cd ab 89 67 45 23 01 bc 5c 0e 6c 30 f4 f4 b9 27 88 66 ca "
    "c8 2c b6 e7 ae af 79 cf 55 af a7 6a 51 17 08 f5 e9 30 89 86";

/* The same with ground truth (squat, lift 3, progress 0.5) and no drops; 110 bytes. */
static const char *const VEC_SAMPLE_TRUTH =
    "45 58 03 01 36 00 01 00 20 5e 27 00 00 00 00 00 02 01 00 00 05 00 00 00 "
    "1c 0c 21 0c 64 32 5a 32 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 "
    "00 00 e0 3f 03 00 00 00 05 73 71 75 61 74 88 77 66 55 44 33 22 11 ef cd "
    "ab 89 67 45 23 01 63 2f 6b 65 86 44 72 3d 97 1e ad 5c 97 22 de f4 3a 82 "
    "24 ad 1e 9c 9e 72 fd 99 e9 87 30 b2 9a 84";

/* HELLO, host_seq 5, receiver session 0; 64 bytes. */
static const char *const VEC_HELLO =
    "45 58 03 03 08 00 00 00 05 00 00 00 00 00 00 00 ef cd ab 89 67 45 23 01 "
    "00 00 00 00 00 00 00 00 25 f1 43 4d db 79 c4 d2 f1 8d dd 73 42 cd 83 e8 "
    "df e7 e5 9d 15 78 27 87 7d ea 89 a2 2c b8 9f b6";

/* CHALLENGE answering HELLO 5: lifetime 1000 ms, challenge a0..af, unique id
 * 10..1b and four zeros, firmware "exostudy-c 3.0"; 112 bytes. */
static const char *const VEC_CHALLENGE =
    "45 58 03 04 38 00 00 00 05 00 00 00 e8 03 00 00 a0 a1 a2 a3 a4 a5 a6 a7 "
    "a8 a9 aa ab ac ad ae af 10 11 12 13 14 15 16 17 18 19 1a 1b 00 00 00 00 "
    "65 78 6f 73 74 75 64 79 2d 63 20 33 2e 30 00 00 88 77 66 55 44 33 22 11 "
    "ef cd ab 89 67 45 23 01 f3 38 9f 7f 37 97 91 31 f4 1d f7 00 48 9b 0e 9a "
    "ae fe 17 49 d9 ec e3 29 6e 9c 78 9d 43 cc 19 69";

/* JOIN, host_seq 6, answering that challenge; 80 bytes. */
static const char *const VEC_JOIN =
    "45 58 03 05 18 00 00 00 06 00 00 00 00 00 00 00 a0 a1 a2 a3 a4 a5 a6 a7 "
    "a8 a9 aa ab ac ad ae af ef cd ab 89 67 45 23 01 88 77 66 55 44 33 22 11 "
    "a6 d2 6e 77 be 29 7e 94 ae 28 0f b2 d0 53 6b 68 ef e8 b9 0a a7 10 6f 67 "
    "21 9a 56 10 3e 06 0a 15";

/* COMMAND, host_seq 7, echo_seq 258, lock left only; 68 bytes. */
static const char *const VEC_COMMAND =
    "45 58 03 02 0c 00 00 00 07 00 00 00 02 01 00 00 01 00 00 00 ef cd ab 89 "
    "67 45 23 01 88 77 66 55 44 33 22 11 8d ca 23 60 a0 45 a1 6b d5 f2 72 ea "
    "d1 98 69 48 a6 fb 6d 3d c0 fd 65 62 4a 02 c0 68 cc 3d 0b 44";

/* COMMAND, host_seq 8, echo_seq 259, lock both, STOP_HEARTBEAT; 68 bytes. */
static const char *const VEC_COMMAND_HEARTBEAT =
    "45 58 03 02 0c 00 01 00 08 00 00 00 03 01 00 00 03 00 00 00 ef cd ab 89 "
    "67 45 23 01 88 77 66 55 44 33 22 11 c5 ce 33 ad bc be f3 da 37 94 d2 ff "
    "17 62 08 4a 08 6b db a7 df ba ba 4f b0 2b aa 68 f6 ed 87 d5";

/* VERSION from a device that speaks version 3 only; 44 bytes. */
static const char *const VEC_VERSION =
    "45 58 03 06 04 00 00 00 03 03 00 00 d4 e3 a8 ab 6b 4f ac 04 cb cb 16 35 "
    "5b 65 b6 5d 1e 5a 17 80 5a 3c 7a e7 3c 79 10 80 9a f7 6f bd";

#endif /* EXO_TEST_VECTORS_H */
