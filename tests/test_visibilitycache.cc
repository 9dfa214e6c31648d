// VisibilityCache: every report comes back exactly (each step size the code distinguishes, its
// edges included), the byte count is the code's, and the budget is never exceeded, also by
// threads offering at once. Solver-level equivalence (cached iterations give the sweeps' bits)
// is in test_radiosity.cc.
#include "vdbrad/VisibilityCache.h"

#include <gtest/gtest.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstdint>
#include <random>
#include <utility>
#include <vector>

using vdbrad::VisibilityCache;

namespace {

constexpr uint32_t kNone = VisibilityCache::kNone;

// The code's size for a report, from its definition: one byte per voxel, plus 2 after a step
// outside [-127, 125] that fits 16 bits, plus 4 after a larger one.
size_t
codeBytes(const std::vector<uint32_t>& seen)
{
    size_t bytes = 0;
    int64_t last = 0;
    for (uint32_t y : seen) {
        ++bytes;
        if (y == kNone) continue;
        const int64_t step = int64_t(y) - last;
        last = y;
        if (step < -127 || step > 125) bytes += (step >= -32768 && step <= 32767) ? 2 : 4;
    }
    return bytes;
}

std::vector<std::pair<uint32_t, uint32_t>>
replayed(const VisibilityCache& cache, size_t k)
{
    std::vector<std::pair<uint32_t, uint32_t>> out;
    VisibilityCache::Reader reader(cache, k);
    for (uint32_t x = 0, y = 0; x < cache.voxels(); ++x) {
        if (reader.next(y)) out.emplace_back(x, y);
    }
    return out;
}

std::vector<std::pair<uint32_t, uint32_t>>
expected(const std::vector<uint32_t>& seen)
{
    std::vector<std::pair<uint32_t, uint32_t>> out;
    for (uint32_t x = 0; x < seen.size(); ++x) {
        if (seen[x] != kNone) out.emplace_back(x, seen[x]);
    }
    return out;
}

// A random report: a quarter sees nothing, the rest steps of every code size from the last
// voxel seen, around an offset that may be near 0 or near the top of the 32-bit range.
std::vector<uint32_t>
randomReport(size_t n, std::mt19937& rng, uint32_t base)
{
    std::vector<uint32_t> seen(n);
    int64_t last = base;
    for (uint32_t& y : seen) {
        const int kind = int(rng() % 8);
        if (kind < 2) { y = kNone; continue; }
        int64_t step = 0;
        if (kind < 5) step = int64_t(rng() % 253) - 127;            // one byte
        else if (kind < 7) step = int64_t(rng() % 65536) - 32768;   // 16 bits
        else step = int64_t(rng() % 2000000) - 1000000;             // absolute
        const int64_t v = last + step;
        if (v < 0 || v >= int64_t(kNone)) { y = uint32_t(base); last = base; continue; }
        y = uint32_t(v);
        last = v;
    }
    return seen;
}

} // namespace

TEST(VisibilityCache, ReportsComeBackExactlyAtEveryStepSize)
{
    // The edges of each code: steps -127 and 125 (one byte), -128, 126, 32767 and -32768 (16
    // bits), 32768 and -32769 (absolute), between entries that see nothing; then positions 0
    // and kNone - 1 (the largest), and the first entry's step from 0.
    int64_t at = 40000;
    std::vector<uint32_t> edges = {uint32_t(at)};
    for (int64_t step : {0, 125, -127, 126, -128, 32767, -32768, 32768, -32769, 1, -1}) {
        at += step;
        edges.push_back(uint32_t(at));
        edges.push_back(kNone);
    }
    for (uint32_t y : {0u, kNone - 1, kNone - 1, kNone - 126, 0u}) edges.push_back(y);
    std::mt19937 rng(7);
    const std::vector<std::vector<uint32_t>> reports = {edges, std::vector<uint32_t>(300, kNone),
        randomReport(5000, rng, 0), randomReport(5000, rng, 1u << 31),
        randomReport(5000, rng, kNone - 2000000)};
    for (const auto& r : reports) ASSERT_LE(r.size(), 5000u);
    size_t bytes = 0, codeSizes[3] = {0, 0, 0};
    for (size_t k = 0; k < reports.size(); ++k) {
        std::vector<uint32_t> seen = reports[k];
        seen.resize(5000, kNone);
        VisibilityCache cache(1, seen.size(), size_t(1) << 30);
        std::vector<uint8_t> scratch;
        ASSERT_TRUE(cache.offer(0, seen.data(), scratch));
        ASSERT_TRUE(cache.has(0));
        EXPECT_EQ(replayed(cache, 0), expected(seen)) << "report " << k;
        EXPECT_EQ(cache.bytes(), codeBytes(seen)) << "report " << k;
        EXPECT_EQ(cache.kept(), 1u);
        bytes += cache.bytes();
        int64_t last = 0;
        for (uint32_t y : seen) {
            if (y == kNone) continue;
            const int64_t step = int64_t(y) - last;
            last = y;
            ++codeSizes[(step >= -127 && step <= 125) ? 0 : (step >= -32768 && step <= 32767)
                ? 1 : 2];
        }
    }
    // Every code size was exercised many times.
    for (size_t c : codeSizes) EXPECT_GT(c, 500u);
    EXPECT_LT(bytes, 5 * 5 * 5000u);
}

TEST(VisibilityCache, KeepsReportsOnlyWhileTheBudgetLasts)
{
    std::mt19937 rng(11);
    const size_t n = 2000;
    std::vector<std::vector<uint32_t>> reports;
    for (int k = 0; k < 3; ++k) reports.push_back(randomReport(n, rng, 1000));
    const size_t a = codeBytes(reports[0]), b = codeBytes(reports[1]), c = codeBytes(reports[2]);
    // Room for the first two and not for the third; then a fourth small one fits what is left.
    VisibilityCache cache(4, n, a + b + c - 1);
    std::vector<uint8_t> scratch;
    EXPECT_TRUE(cache.offer(0, reports[0].data(), scratch));
    EXPECT_TRUE(cache.offer(1, reports[1].data(), scratch));
    EXPECT_FALSE(cache.offer(2, reports[2].data(), scratch));
    EXPECT_FALSE(cache.has(2));
    EXPECT_EQ(cache.bytes(), a + b);
    const std::vector<uint32_t> dark(n, kNone);   // n bytes
    ASSERT_LE(n, c - 1);
    EXPECT_TRUE(cache.offer(3, dark.data(), scratch));
    EXPECT_EQ(cache.kept(), 3u);
    EXPECT_EQ(cache.bytes(), a + b + n);
    EXPECT_EQ(replayed(cache, 1), expected(reports[1]));
    EXPECT_TRUE(replayed(cache, 3).empty());
}

TEST(VisibilityCache, ThreadsOfferingAtOnceNeverExceedTheBudget)
{
    // 64 reports of one size, room for 10.5 of them: exactly 10 are kept, whichever.
    const size_t n = 4096, directions = 64;
    const std::vector<uint32_t> seen(n, 1000);   // one 16-bit step, then steps of 0
    const size_t each = codeBytes(seen);
    ASSERT_EQ(each, n + 2);
    VisibilityCache cache(directions, n, each * 21 / 2);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, directions, 1),
        [&](const tbb::blocked_range<size_t>& r) {
            std::vector<uint8_t> scratch;
            for (size_t k = r.begin(); k != r.end(); ++k) cache.offer(k, seen.data(), scratch);
        });
    EXPECT_EQ(cache.kept(), 10u);
    EXPECT_EQ(cache.bytes(), 10 * each);
    size_t has = 0;
    for (size_t k = 0; k < directions; ++k) {
        if (!cache.has(k)) continue;
        ++has;
        EXPECT_EQ(replayed(cache, k), expected(seen));
    }
    EXPECT_EQ(has, 10u);
}
