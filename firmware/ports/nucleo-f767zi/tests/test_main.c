/* test_main.c - run every group and print the totals. */
#include "../../test-harness/harness.h"
#include "tests.h"

int harness_passed;
int harness_failed;

int main(void)
{
    test_checksum();
    test_ipv4_udp();
    test_arp();
    test_stack();
    test_prov();
    test_timing();
    test_flood();
    printf("%d passed, %d failed\n", harness_passed, harness_failed);
    return harness_failed == 0 ? 0 : 1;
}
