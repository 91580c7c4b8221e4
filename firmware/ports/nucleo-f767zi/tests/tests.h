/* tests.h - the test groups run by test_main.c. */
#ifndef TESTS_H
#define TESTS_H

#include <stdint.h>

void test_checksum(void);
void test_ipv4_udp(void);
void test_arp(void);
void test_stack(void);
void test_prov(void);
void test_timing(void);
void test_flood(void);

#endif /* TESTS_H */
