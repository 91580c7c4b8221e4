/* The time base's 64-bit extension (lost wraps included) and the watchdog's worst cases. */
#include "../../test-harness/harness.h"
#include "tests.h"

#include "../iwdg_timing.h"
#include "../timebase_ext.h"

#define WRAP (UINT64_C(1) << 32)

/* The two counters as the hardware would show them `t_us` after both started at the
 * given values (the coarse one ticks every 500 us from a phase `phase_us`). */
static uint32_t fine_at(uint32_t fine0, uint64_t t_us)
{
    return (uint32_t)(fine0 + t_us);
}

static uint32_t coarse_at(uint32_t coarse0, uint64_t phase_us, uint64_t t_us)
{
    return (uint32_t)(coarse0 + (t_us + phase_us) / TB_COARSE_TICK_US);
}

static uint64_t read_at(tb_ext *t, uint32_t fine0, uint32_t coarse0, uint64_t phase, uint64_t us)
{
    return tb_ext_update(t, fine_at(fine0, us), coarse_at(coarse0, phase, us));
}

static void regular_reads_across_a_wrap(void)
{
    /* Start 5 ms before TIM2 wraps; read every 10 ms for 20 ms: one seen wrap. */
    uint32_t fine0 = 0xFFFFFFFFu - 4999u;
    tb_ext t;
    tb_ext_init(&t, fine0, coarse_at(7u, 0u, 0u));
    CHECK_EQ(read_at(&t, fine0, 7u, 0u, 10000u), 10000u);
    CHECK_EQ(read_at(&t, fine0, 7u, 0u, 20000u), 20000u);
    CHECK_EQ(t.lost_wraps, 0u);
    CHECK_EQ(t.mismatches, 0u);
}

static void lost_wraps_are_recovered(void)
{
    /* The loop stops for one, two and five whole TIM2 periods plus a few ms: with the
     * fine counter alone, each stall would look like the few ms. */
    const uint64_t stalls[] = {WRAP + 3000u, 2u * WRAP + 40000u, 5u * WRAP + 123u,
                               WRAP - 1000u, WRAP + 0u};
    for (unsigned phase = 0; phase < TB_COARSE_TICK_US; phase += 137u) {
        uint64_t now = 0u;
        tb_ext t;
        tb_ext_init(&t, 12345u, coarse_at(99u, phase, 0u));
        for (unsigned i = 0; i < sizeof stalls / sizeof stalls[0]; i++) {
            now += stalls[i];
            CHECK_EQ(read_at(&t, 12345u, 99u, phase, now), now);
            now += 10000u; /* and a normal period after it */
            CHECK_EQ(read_at(&t, 12345u, 99u, phase, now), now);
        }
        CHECK_EQ(t.lost_wraps, 1u + 2u + 5u + 0u + 1u);
        CHECK_EQ(t.mismatches, 0u);
    }
}

static void the_coarse_counter_wraps_too(void)
{
    /* TIM5 wraps after 2^32 ticks (24.8 days): start it 3 ticks before. */
    uint32_t coarse0 = 0xFFFFFFFDu;
    tb_ext t;
    tb_ext_init(&t, 0u, coarse0);
    CHECK_EQ(read_at(&t, 0u, coarse0, 0u, 10000u), 10000u);
    CHECK_EQ(read_at(&t, 0u, coarse0, 0u, WRAP + 20000u), WRAP + 20000u);
    CHECK_EQ(t.lost_wraps, 1u);
}

static void a_dead_coarse_counter_is_detected(void)
{
    /* TIM5 not counting: the extension is the fine difference alone (one wrap still
     * handled), a lost wrap cannot be recovered, and every read is a mismatch. */
    tb_ext t;
    tb_ext_init(&t, 0xFFFFF000u, 0u);
    CHECK_EQ(tb_ext_update(&t, 0x00001000u, 0u), 0x2000u);
    CHECK_EQ(t.mismatches, 1u);
    CHECK_EQ(tb_ext_update(&t, 0x00001000u + 3000u, 0u), 0x2000u + 3000u);
    CHECK_EQ(t.mismatches, 2u);
    CHECK_EQ(t.lost_wraps, 0u);
}

static void never_goes_back(void)
{
    /* Pseudo-random gaps (10 us .. 3 wraps) and read order jitter: monotonic, exact. */
    uint32_t x = 2463534242u;
    uint64_t now = 0u;
    tb_ext t;
    tb_ext_init(&t, 777u, coarse_at(5u, 250u, 0u));
    int exact = 1, monotonic = 1;
    uint64_t prev = 0u;
    for (int i = 0; i < 20000; i++) {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        uint64_t gap = (i % 1000 == 999) ? (uint64_t)(x % 3u + 1u) * WRAP + x % 100000u
                                         : 10u + x % 20000u;
        now += gap;
        uint64_t got = read_at(&t, 777u, 5u, 250u, now);
        exact &= got == now;
        monotonic &= got >= prev;
        prev = got;
    }
    CHECK(exact);
    CHECK(monotonic);
    CHECK_EQ(t.mismatches, 0u);
}

static void watchdog_worst_cases(void)
{
    uint32_t slowest = iwdg_timeout_us(IWDG_RELOAD, IWDG_DIVIDER, IWDG_LSI_MIN_HZ);
    uint32_t fastest = iwdg_timeout_us(IWDG_RELOAD, IWDG_DIVIDER, IWDG_LSI_MAX_HZ);
    CHECK(slowest <= IWDG_RELEASE_MAX_US);
    CHECK_EQ(slowest, 104942u); /* 446 * 4 / 17 kHz */
    CHECK_EQ(fastest, 37958u);  /* 446 * 4 / 47 kHz */
    CHECK(fastest >= 3u * IWDG_KICK_PERIOD_US);
    /* The old setting (prescaler 8, reload 400) was 188 ms at the slowest LSI. */
    CHECK(iwdg_timeout_us(400u, 8u, IWDG_LSI_MIN_HZ) > IWDG_RELEASE_MAX_US);
    /* One more reload step would still be inside 110 ms only up to 467. */
    CHECK(iwdg_timeout_us(466u, 4u, IWDG_LSI_MIN_HZ) <= IWDG_RELEASE_MAX_US);
    CHECK(iwdg_timeout_us(467u, 4u, IWDG_LSI_MIN_HZ) > IWDG_RELEASE_MAX_US);
}

void test_timing(void)
{
    regular_reads_across_a_wrap();
    lost_wraps_are_recovered();
    the_coarse_counter_wraps_too();
    a_dead_coarse_counter_is_detected();
    never_goes_back();
    watchdog_worst_cases();
}
