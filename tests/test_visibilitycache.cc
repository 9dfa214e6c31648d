// VisibilityCache: every report comes back exactly in both codes (each step size a code
// distinguishes, its edges included), the byte count is the code's, and the budget is never
// exceeded, also by threads offering at once. Solver-level equivalence (cached iterations give
// the sweeps' bits, in either code) is in test_radiosity.cc.
#include "vdbrad/sweep/VisibilityCache.h"

#include <gtest/gtest.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

using vdbrad::VisibilityCache;
using Code = VisibilityCache::Code;

namespace {

constexpr uint32_t kNone = VisibilityCache::kNone;

// f(step) for every entry of @a seen that sees something.
template<typename F>
void
forSteps(const std::vector<uint32_t>& seen, F&& f)
{
    int64_t last = 0;
    for (uint32_t y : seen) {
        if (y == kNone) continue;
        f(int64_t(y) - last);
        last = y;
    }
}

// The byte code's size for a report, from its definition: one byte per voxel, plus 2 after a
// step outside [-127, 125] that fits 16 bits, plus 4 after a larger one, in whole words.
size_t
byteCodeBytes(const std::vector<uint32_t>& seen)
{
    size_t bytes = seen.size();
    forSteps(seen, [&](int64_t step) {
        if (step < -127 || step > 125) bytes += (step >= -32768 && step <= 32767) ? 2 : 4;
    });
    return (bytes + 3) / 4 * 4;
}

// The report's table from its definition: the 12 most frequent steps in [-2048, 2048), by
// decreasing count, ties to the smaller step.
std::vector<int64_t>
tableOf(const std::vector<uint32_t>& seen)
{
    std::map<int64_t, size_t> counts;
    forSteps(seen, [&](int64_t step) {
        if (step >= -2048 && step < 2048) ++counts[step];
    });
    std::vector<std::pair<size_t, int64_t>> byCount;
    for (const auto& [step, count] : counts) byCount.emplace_back(count, step);
    std::stable_sort(byCount.begin(), byCount.end(),
        [](const auto& a, const auto& b) { return a.first > b.first; });
    std::vector<int64_t> table;
    for (size_t i = 0; i < byCount.size() && i < 12; ++i) table.push_back(byCount[i].second);
    return table;
}

// Nibbles of one entry: 1 for "sees nothing" or a table step, 3 for another 8-bit step, 5 for
// a 16-bit one, 9 for an absolute position. code sizes: 0, 1, 2, 3 in that order.
int
nibblesOf(int64_t step, const std::vector<int64_t>& table, int* kind = nullptr)
{
    int k = 0;
    if (std::find(table.begin(), table.end(), step) != table.end()) k = 0;
    else if (step >= -128 && step <= 127) k = 1;
    else if (step >= -32768 && step <= 32767) k = 2;
    else k = 3;
    if (kind) *kind = k;
    return std::array<int, 4>{1, 3, 5, 9}[size_t(k)];
}

// The code's size for a report, from its definition: a zero word and the 12-step table (52
// bytes), then the entries' nibbles, two to a byte, in whole words.
size_t
codeBytes(const std::vector<uint32_t>& seen)
{
    const std::vector<int64_t> table = tableOf(seen);
    size_t nibbles = size_t(std::count(seen.begin(), seen.end(), kNone));
    forSteps(seen, [&](int64_t step) { nibbles += size_t(nibblesOf(step, table)); });
    return 52 + (nibbles + 7) / 8 * 4;
}

std::vector<std::pair<uint32_t, uint32_t>>
replayed(const VisibilityCache& cache, size_t k)
{
    std::vector<std::pair<uint32_t, uint32_t>> out;
    auto read = [&](auto reader) {
        for (uint32_t x = 0, y = 0; x < cache.voxels(); ++x) {
            if (reader.next(y)) out.emplace_back(x, y);
        }
    };
    if (cache.code() == Code::Bytes) read(VisibilityCache::ByteReader(cache, k));
    else read(VisibilityCache::Reader(cache, k));
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
        if (kind == 2) step = int64_t(rng() % 12) - 6;              // tabled
        else if (kind < 5) step = int64_t(rng() % 256) - 128;       // one byte
        else if (kind < 7) step = int64_t(rng() % 65536) - 32768;   // 16 bits
        else step = int64_t(rng() % 2000000) - 1000000;             // absolute
        const int64_t v = last + step;
        if (v < 0 || v >= int64_t(kNone)) { y = uint32_t(base); last = base; continue; }
        y = uint32_t(v);
        last = v;
    }
    return seen;
}

// @a edges, then each given step from the last position, followed by an entry that sees
// nothing, then positions 0 and kNone - 1 (the largest): the first entry's step is from 0.
std::vector<uint32_t>
withEdges(std::vector<uint32_t> edges, int64_t at, std::initializer_list<int64_t> steps)
{
    for (int64_t step : steps) {
        at += step;
        edges.push_back(uint32_t(at));
        edges.push_back(kNone);
    }
    for (uint32_t y : {0u, kNone - 1, kNone - 1, kNone - 126, 0u}) edges.push_back(y);
    return edges;
}

// @a edges, a dark report and random ones at both ends of the 32-bit range, 5000 entries each.
std::vector<std::vector<uint32_t>>
withRandomReports(std::vector<uint32_t> edges)
{
    std::mt19937 rng(7);
    std::vector<std::vector<uint32_t>> reports = {std::move(edges),
        std::vector<uint32_t>(300, kNone), randomReport(5000, rng, 0),
        randomReport(5000, rng, 1u << 31), randomReport(5000, rng, kNone - 2000000)};
    for (auto& r : reports) {
        EXPECT_LE(r.size(), 5000u);
        r.resize(5000, kNone);
    }
    return reports;
}

} // namespace

TEST(VisibilityCache, ReportsComeBackExactlyAtEveryStepSize)
{
    // Twelve frequent steps fill the table, then the edges of each escape, each once: 8-bit
    // -128 and 127, 16-bit -129, 128, 32767 and -32768, absolute 32768 and -32769, between
    // entries that see nothing; then positions 0 and kNone - 1 (the largest), and the first
    // entry's step from 0.
    int64_t at = 40000;
    std::vector<uint32_t> frequent = {uint32_t(at)};
    for (int r = 0; r < 40; ++r) {
        for (int64_t step : {1, 2, 3, 4, 5, 6, -1, -2, -3, -4, -5, 57}) {
            at += step;
            frequent.push_back(uint32_t(at));
        }
    }
    const std::vector<uint32_t> edges = withEdges(frequent, at,
        {0, 127, -128, 128, -129, 32767, -32768, 32768, -32769, 7, -7});
    const std::vector<std::vector<uint32_t>> reports = withRandomReports(edges);
    size_t bytes = 0, codeSizes[4] = {0, 0, 0, 0};
    for (size_t k = 0; k < reports.size(); ++k) {
        const std::vector<uint32_t>& seen = reports[k];
        VisibilityCache cache(1, seen.size(), size_t(1) << 30, Code::Nibbles);
        std::vector<uint8_t> scratch;
        ASSERT_TRUE(cache.offer(0, seen.data(), scratch));
        ASSERT_TRUE(cache.has(0));
        EXPECT_EQ(replayed(cache, 0), expected(seen)) << "report " << k;
        EXPECT_EQ(cache.bytes(), codeBytes(seen)) << "report " << k;
        EXPECT_EQ(cache.kept(), 1u);
        bytes += cache.bytes();
        const std::vector<int64_t> table = tableOf(seen);
        const std::array<int32_t, 12> kept = VisibilityCache::table(seen.data(), seen.size());
        for (size_t i = 0; i < 12; ++i) {
            EXPECT_EQ(kept[i], i < table.size() ? int32_t(table[i]) : VisibilityCache::kUnused)
                << "report " << k << " entry " << i;
        }
        forSteps(seen, [&](int64_t step) {
            int kind = 0;
            nibblesOf(step, table, &kind);
            ++codeSizes[kind];
        });
    }
    // Every code size was exercised many times, and the edges' table holds the frequent steps.
    for (size_t c : codeSizes) EXPECT_GT(c, 500u);
    EXPECT_EQ(tableOf(edges).size(), 12u);
    EXPECT_EQ(tableOf(edges)[11], 57);
    EXPECT_LT(bytes, 5 * 5 * 5000u);
}

TEST(VisibilityCache, ByteCodeReportsComeBackExactlyAtEveryStepSize)
{
    // The edges of each byte code: steps -127 and 125 (one byte), -128, 126, 32767 and -32768 (16
    // bits), 32768 and -32769 (absolute), between entries that see nothing; then positions 0
    // and kNone - 1 (the largest), and the first entry's step from 0.
    const std::vector<std::vector<uint32_t>> reports = withRandomReports(withEdges({40000},
        40000, {0, 125, -127, 126, -128, 32767, -32768, 32768, -32769, 1, -1}));
    size_t bytes = 0, codeSizes[3] = {0, 0, 0};
    for (size_t k = 0; k < reports.size(); ++k) {
        const std::vector<uint32_t>& seen = reports[k];
        VisibilityCache cache(1, seen.size(), size_t(1) << 30, Code::Bytes);
        std::vector<uint8_t> scratch;
        ASSERT_TRUE(cache.offer(0, seen.data(), scratch));
        ASSERT_TRUE(cache.has(0));
        EXPECT_EQ(replayed(cache, 0), expected(seen)) << "report " << k;
        EXPECT_EQ(cache.bytes(), byteCodeBytes(seen)) << "report " << k;
        EXPECT_EQ(cache.kept(), 1u);
        bytes += cache.bytes();
        forSteps(seen, [&](int64_t step) {
            ++codeSizes[(step >= -127 && step <= 125) ? 0 : (step >= -32768 && step <= 32767)
                ? 1 : 2];
        });
    }
    // Every code size was exercised many times.
    for (size_t c : codeSizes) EXPECT_GT(c, 500u);
    EXPECT_LT(bytes, 5 * 5 * 5000u);
}

TEST(VisibilityCache, TheCodeIsBytesWhereTheBudgetHoldsEveryDirection)
{
    // 2 bytes per voxel and direction (typicalBytes) or more: bytes, the faster replay; less:
    // nibbles, the denser code. Either way a report comes back exactly.
    const size_t n = 1000, directions = 10;
    EXPECT_EQ(VisibilityCache(directions, n, directions * 2 * n).code(), Code::Bytes);
    EXPECT_EQ(VisibilityCache(directions, n, SIZE_MAX).code(), Code::Bytes);
    EXPECT_EQ(VisibilityCache(directions, n, directions * 2 * n - 1).code(), Code::Nibbles);
    EXPECT_EQ(VisibilityCache(directions, n, 0).code(), Code::Nibbles);
}

TEST(VisibilityCache, FrequentStepsTakeOneNibble)
{
    // A wall seeing a wall: steps of 1 with a row jump every 8 voxels, a fifth seeing nothing:
    // half a byte per voxel plus the table (8000 voxels: whole words).
    const size_t n = 8000;
    std::vector<uint32_t> seen(n);
    uint32_t y = 100;
    for (size_t x = 0; x < n; ++x) {
        if (x % 5 == 4) { seen[x] = kNone; continue; }
        y += (x % 8 == 7) ? 57 : 1;
        seen[x] = y;
    }
    VisibilityCache cache(1, n, size_t(1) << 30, Code::Nibbles);
    std::vector<uint8_t> scratch;
    ASSERT_TRUE(cache.offer(0, seen.data(), scratch));
    EXPECT_EQ(cache.bytes(), 52 + n / 2);
    EXPECT_EQ(replayed(cache, 0), expected(seen));
}

TEST(VisibilityCache, KeepsReportsOnlyWhileTheBudgetLasts)
{
    std::mt19937 rng(11);
    const size_t n = 2000;
    std::vector<std::vector<uint32_t>> reports;
    for (int k = 0; k < 3; ++k) reports.push_back(randomReport(n, rng, 1000));
    const size_t a = codeBytes(reports[0]), b = codeBytes(reports[1]), c = codeBytes(reports[2]);
    // Room for the first two and not for the third; then a fourth small one fits what is left.
    VisibilityCache cache(4, n, a + b + c - 1, Code::Nibbles);
    std::vector<uint8_t> scratch;
    EXPECT_TRUE(cache.offer(0, reports[0].data(), scratch));
    EXPECT_TRUE(cache.offer(1, reports[1].data(), scratch));
    EXPECT_FALSE(cache.offer(2, reports[2].data(), scratch));
    EXPECT_FALSE(cache.has(2));
    EXPECT_EQ(cache.bytes(), a + b);
    const std::vector<uint32_t> dark(n, kNone);   // n nibbles
    const size_t darkBytes = 52 + (n + 7) / 8 * 4;
    ASSERT_LE(darkBytes, c - 1);
    EXPECT_TRUE(cache.offer(3, dark.data(), scratch));
    EXPECT_EQ(cache.kept(), 3u);
    EXPECT_EQ(cache.bytes(), a + b + darkBytes);
    EXPECT_EQ(replayed(cache, 1), expected(reports[1]));
    EXPECT_TRUE(replayed(cache, 3).empty());
}

TEST(VisibilityCache, PoolsKeepTheirShareOfTheBudget)
{
    // Two pools of two directions each get half the budget: the first pool's second big report
    // no longer takes what the second pool's big report needs; a direction in no pool (another
    // rank's) is never kept.
    std::mt19937 rng(5);
    const size_t n = 3000;
    const std::vector<uint32_t> big = randomReport(n, rng, 1000), small(n, kNone);
    const size_t B = codeBytes(big), S = codeBytes(small);
    ASSERT_GT(B, 2 * S);
    auto kept = [&](bool pooled) {
        VisibilityCache cache(5, n, 2 * (B + S), Code::Nibbles);
        if (pooled) cache.pools({0, 0, 1, 1, VisibilityCache::kNoPool});
        std::vector<uint8_t> scratch;
        std::string out;
        for (size_t k = 0; k < 4; ++k) {
            out += cache.offer(k, (k == 2 ? small : big).data(), scratch) ? '1' : '0';
        }
        out += cache.offer(4, small.data(), scratch) ? '1' : '0';
        EXPECT_LE(cache.bytes(), 2 * (B + S));
        return out;
    };
    EXPECT_EQ(kept(false), "11101");
    EXPECT_EQ(kept(true), "10110");
}

TEST(VisibilityCache, ThreadsOfferingAtOnceNeverExceedTheBudget)
{
    // 64 reports of one size, room for 10.5 of them: exactly 10 are kept, whichever.
    const size_t n = 4096, directions = 64;
    const std::vector<uint32_t> seen(n, 1000);   // steps 1000 then 0: both in the table
    const size_t each = codeBytes(seen);
    ASSERT_EQ(each, 52 + n / 2);
    VisibilityCache cache(directions, n, each * 21 / 2, Code::Nibbles);
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
