/*
 * vectors.h - the four test datagrams of docs/device-protocol.md ("Test vectors"),
 * copied byte for byte. Key 00 01 .. 1f, device session 0x1122334455667788, host
 * session 0x0123456789abcdef.
 */
#ifndef EXO_TEST_VECTORS_H
#define EXO_TEST_VECTORS_H

#define VEC_DEVICE_SESSION 0x1122334455667788u
#define VEC_HOST_SESSION 0x0123456789abcdefu

/* SAMPLE, seq 258, t 2.58 s, counts (3100, 3105, 12900, 12890), status 0x005, device
 * dropped 1 command for a failed tag and 2 as replays; 88 bytes. */
static const char *const VEC_SAMPLE =
    "45 58 02 01 20 00 00 00 20 5e 27 00 00 00 00 00 02 01 00 00 05 00 00 00"
    "1c 0c 21 0c 64 32 5a 32 01 00 00 00 02 00 00 00 88 77 66 55 44 33 22 11"
    "ef cd ab 89 67 45 23 01 73 35 b8 0c 00 63 8d 60 2e 17 63 0b 28 94 d1 bc"
    "84 64 1a e4 1a 5a 61 78 19 40 10 2a f8 8e f5 db";

/* The same with ground truth (squat, lift 3, progress 0.5) and no drops; 106 bytes. */
static const char *const VEC_SAMPLE_TRUTH =
    "45 58 02 01 32 00 01 00 20 5e 27 00 00 00 00 00 02 01 00 00 05 00 00 00"
    "1c 0c 21 0c 64 32 5a 32 00 00 00 00 00 00 00 00 00 00 00 00 00 00 e0 3f"
    "03 00 00 00 05 73 71 75 61 74 88 77 66 55 44 33 22 11 ef cd ab 89 67 45"
    "23 01 d4 7b a9 ea e2 7e 6a 21 08 67 e6 ed e8 74 81 1b b4 e3 98 5b 24 f3"
    "70 a8 74 8f f7 03 36 a5 55 fa";

/* COMMAND, host_seq 7, echo_seq 258, lock left only; 68 bytes. */
static const char *const VEC_COMMAND =
    "45 58 02 02 0c 00 01 00 07 00 00 00 02 01 00 00 01 00 00 00 ef cd ab 89"
    "67 45 23 01 88 77 66 55 44 33 22 11 b7 9d 70 a8 f4 26 b0 6d 08 d7 e4 47"
    "c6 63 55 29 32 2d 55 71 63 b3 ec 2c ba 75 8d 38 7e e2 99 df";

/* HELLO, host_seq 1, device session not yet known (0); 64 bytes. */
static const char *const VEC_HELLO =
    "45 58 02 03 08 00 00 00 01 00 00 00 00 00 00 00 ef cd ab 89 67 45 23 01"
    "00 00 00 00 00 00 00 00 2d 4d 50 f0 5f 0b ce c8 63 6e b2 21 71 6d 50 02"
    "8e b9 5d 79 03 a6 1d b7 4d 7f 4f cf 18 6d 2e 9b";

#endif /* EXO_TEST_VECTORS_H */
