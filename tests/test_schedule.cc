// SweepSchedule: how the directions are dealt to sign patterns and accumulator groups, the
// visiting orders, the fixed-order reduction and cancellation.
#include "vdbrad/core/Errors.h"
#include "vdbrad/sweep/SweepSchedule.h"

#include "CanonicalScene.h"

#include <gtest/gtest.h>

#include <openvdb/openvdb.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <mutex>
#include <set>

using namespace vdbrad;

namespace {

class SweepScheduleTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }
};

// Cancels once asked about a given percentage.
struct CancelAt : openvdb::util::NullInterrupter
{
    explicit CancelAt(int p) : percent(p) {}
    bool wasInterrupted(int p) override { return p >= percent; }
    int percent;
};

} // namespace

TEST_F(SweepScheduleTest, EveryDirectionIsSweptByExactlyOneGroupOfItsPattern)
{
    const Scene scene = test::canonicalScene("cornell", 16);
    for (int count : {1, 2, 7, 120, 967}) {
        SweepSchedule::Layout layout;
        layout.sweeps = false;
        const SweepSchedule s(scene.voxels(), DirectionSet::fromCount(count), layout);
        const size_t dirs = s.directions().size();
        std::vector<int> seen(dirs, 0);
        for (int g = 0; g < SweepSchedule::kGroups; ++g) {
            size_t last = 0;
            bool first = true;
            s.forDirections(g, [&](size_t k) {
                ++seen[k];
                // In set order within a group, and served by the group's pattern.
                EXPECT_TRUE(first || k > last);
                first = false;
                last = k;
                const std::vector<size_t>& mine = s.patternOfGroup(g).directions;
                EXPECT_NE(std::find(mine.begin(), mine.end(), k), mine.end());
            });
            // Groups g and g + 4 share a pattern: the two halves of an in-place iteration.
            EXPECT_EQ(SweepSchedule::patternOf(g), SweepSchedule::patternOf(g % 4));
        }
        for (size_t k = 0; k < dirs; ++k) EXPECT_EQ(seen[k], 1) << count << " directions, k " << k;
    }
}

TEST_F(SweepScheduleTest, OrdersArePermutationsWithTheirInverse)
{
    const Scene scene = test::canonicalScene("furnace-sphere", 12);
    SweepSchedule::Layout layout;
    layout.normals = &scene.normals();
    const SweepSchedule s(scene.voxels(), DirectionSet::fromCount(50), layout);
    for (size_t p = 0; p < SweepSchedule::kPatterns; ++p) {
        const SweepSchedule::Pattern& pattern = s.pattern(p);
        ASSERT_FALSE(pattern.empty());   // 50 directions cover every sign pattern
        ASSERT_EQ(pattern.order.size(), scene.size());
        for (size_t k = 0; k < scene.size(); ++k) {
            EXPECT_EQ(pattern.position[pattern.order[k]], k);
            EXPECT_EQ(pattern.sweep->coord(uint32_t(k)), scene.voxels().coord(pattern.order[k]));
        }
        // toPatternOrder() reads voxel i at its position.
        std::vector<float> byVoxel(scene.size() * 2), ordered;
        for (size_t i = 0; i < byVoxel.size(); ++i) byVoxel[i] = float(i);
        s.toPatternOrder(p, byVoxel, ordered, 2);
        for (size_t k = 0; k < scene.size(); ++k) {
            EXPECT_EQ(ordered[2 * k + 1], float(2 * pattern.order[k] + 1));
        }
    }
}

TEST_F(SweepScheduleTest, SumAddsTheGroupsInGroupOrder)
{
    const Scene scene = test::canonicalScene("furnace-box", 6);
    SweepSchedule::Layout layout;
    layout.sweeps = false;
    const SweepSchedule s(scene.voxels(), DirectionSet::fromCount(50), layout);
    const size_t n = scene.size();
    // Group g holds 10^g at every position (group 3 none: an empty accumulator is skipped).
    std::array<std::vector<float>, SweepSchedule::kGroups> acc;
    for (int g = 0; g < SweepSchedule::kGroups; ++g) {
        if (g != 3) acc[size_t(g)].assign(n, float(std::pow(10.0, g)));
    }
    for (size_t i = 0; i < n; i += 7) {
        double sum = 0.0;
        s.sum(acc, i, 1, &sum);
        EXPECT_EQ(sum, 11110111.0);
    }
    // In group order, not any other: 1e8 + 1 - 1e8 in float accumulators added in double is
    // exact, but the order is visible through a float sum.
    std::array<std::vector<float>, SweepSchedule::kGroups> signs;
    signs[0].assign(n, 1e8f);
    signs[1].assign(n, 1.f);
    signs[2].assign(n, -1e8f);
    float f = 0.f;
    s.sum(signs, 0, 1, &f);
    EXPECT_EQ(f, 0.f);   // (1e8 + 1) - 1e8 in float; 1 if groups 0 and 2 were added first
}

TEST_F(SweepScheduleTest, CancellationStopsTheGroupsAndThrows)
{
    const Scene scene = test::canonicalScene("furnace-box", 6);
    SweepSchedule::Layout layout;
    layout.sweeps = false;
    const SweepSchedule s(scene.voxels(), DirectionSet::fromCount(300), layout);
    CancelAt cancel(10);
    SweepProgress progress(&cancel, s.directions().size());
    std::atomic<size_t> swept{0};
    EXPECT_THROW(s.forEachGroup(progress, "test", [](int) { return true; }, [&](int g) {
        s.forDirections(g, [&](size_t) {
            if (progress.cancelled()) return;
            ++swept;
            progress.finished(1);
        });
    }), Cancelled);
    // Every group stops at its next direction once 10 % are done: far fewer than all.
    EXPECT_LT(swept.load(), s.directions().size() / 2);
    // Not cancelled: no throw, and only the selected groups run.
    SweepProgress quiet(nullptr, 1);
    std::set<int> ran;
    std::mutex m;
    s.forEachGroup(quiet, "test", [](int g) { return g < 4; }, [&](int g) {
        std::lock_guard<std::mutex> lock(m);
        ran.insert(g);
    });
    EXPECT_EQ(ran, (std::set<int>{0, 1, 2, 3}));
}
