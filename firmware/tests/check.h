/*
 * check.h - the tests' tiny assertion harness.
 *
 * Every CHECK counts one pass or one failure; a failure prints where and what to
 * stderr and the run goes on, so one broken check does not hide the others. main.c
 * prints only the closing line "N passed, M failed" on stdout (a cross-check from
 * Python reads it) and exits non-zero on any failure.
 */
#ifndef EXO_TEST_CHECK_H
#define EXO_TEST_CHECK_H

#include <stddef.h>
#include <stdint.h>

extern unsigned long check_passed, check_failed;

void check_report(int ok, const char *file, int line, const char *what);
void check_report_u(int ok, const char *file, int line, const char *what, unsigned long long got,
                    unsigned long long want);
void check_report_bytes(int ok, const char *file, int line, const char *what, const uint8_t *got,
                        const uint8_t *want, size_t n);

#define CHECK(cond) check_report((cond) ? 1 : 0, __FILE__, __LINE__, #cond)
#define CHECK_EQ(got, want)                                                                 \
    do {                                                                                     \
        unsigned long long g_ = (unsigned long long)(got), w_ = (unsigned long long)(want); \
        check_report_u(g_ == w_, __FILE__, __LINE__, #got " == " #want, g_, w_);            \
    } while (0)
#define CHECK_BYTES(got, want, n)                                                          \
    check_report_bytes(memcmp((got), (want), (n)) == 0, __FILE__, __LINE__, #got " == " #want, \
                       (got), (want), (n))

/* Parse hex digits (spaces and newlines ignored) into out; returns the byte count. */
size_t hex_bytes(const char *hex, uint8_t *out, size_t cap);

/* The suites, one per core file (main.c runs them in order). */
void test_crypto(void);
void test_wire(void);
void test_session(void);
void test_watchdog(void);
void test_as5048a(void);
void test_device(void);

#endif /* EXO_TEST_CHECK_H */
