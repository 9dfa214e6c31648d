// LeafOrder: the signed lexicographic visiting order (thesis §4.3.3.4) extends the componentwise
// order of every monotone digital line.
#include "vdbrad/sweep/LeafOrder.h"
#include "vdbrad/sweep/LinePartition.h"

#include <gtest/gtest.h>

#include <random>
#include <iostream>
#include <numeric>
#include <set>
#include <unordered_map>

using namespace vdbrad;
using openvdb::Coord;

namespace {

VoxelIndex
randomSet(unsigned seed, int count, int lo, int hi)
{
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> d(lo, hi);
    openvdb::MaskTree mask;
    for (int i = 0; i < count; ++i) mask.setValueOn(Coord(d(rng), d(rng), d(rng)));
    return VoxelIndex(mask);
}

} // namespace

TEST(LeafOrder, IsAPermutationWithLeavesInSignedLexicographicOrder)
{
    const VoxelIndex index = randomSet(3, 4000, -70, 70);
    for (int sx : {-1, 1}) for (int sy : {-1, 1}) for (int sz : {-1, 1}) {
        const LeafOrder order(index, {sx, sy, sz});
        ASSERT_EQ(order.voxels().size(), index.size());
        std::vector<bool> seen(index.size(), false);
        for (uint32_t i : order.voxels()) {
            ASSERT_FALSE(seen[i]);
            seen[i] = true;
        }
        for (size_t k = 1; k < order.leaves().size(); ++k) {
            const Coord a = index.leafOrigin(order.leaves()[k - 1]);
            const Coord b = index.leafOrigin(order.leaves()[k]);
            EXPECT_LT(Coord(sx * a.x(), sy * a.y(), sz * a.z()),
                Coord(sx * b.x(), sy * b.y(), sz * b.z()));
        }
        // The whole voxel sequence is strictly increasing in the signed lexicographic order.
        for (size_t k = 1; k < order.voxels().size(); ++k) {
            const Coord a = index.coord(order.voxels()[k - 1]);
            const Coord b = index.coord(order.voxels()[k]);
            // Leaf-major: compare leaf origins first, then the voxels.
            const Coord la = a & ~7, lb = b & ~7;
            const Coord sa(sx * la.x(), sy * la.y(), sz * la.z());
            const Coord sb(sx * lb.x(), sy * lb.y(), sz * lb.z());
            if (la == lb) {
                EXPECT_LT(Coord(sx * a.x(), sy * a.y(), sz * a.z()),
                    Coord(sx * b.x(), sy * b.y(), sz * b.z()));
            } else {
                EXPECT_LT(sa, sb);
            }
        }
    }
}

TEST(LeafOrder, ExtendsTheComponentwiseOrderOfEveryDirection)
{
    // If q - p has the signs of sigma (components of the same sign or zero), q is ahead of p on
    // any monotone line of direction sigma that holds both, so the sweep must visit p first.
    // Brute force over all pairs of a random set spanning several leaves, negative coordinates
    // included, for directions of every sign pattern.
    const VoxelIndex index = randomSet(11, 1500, -20, 20);
    const std::vector<Coord> directions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, -1}, {3, -2, 1},
        {-5, 4, -3}, {-1, -1, -1}, {0, 0, 1}, {2, 0, -7}};
    for (const Coord& sigma : directions) {
        bool reversed = false;
        const LeafOrder order(index, LeafOrder::baseSigns(sigma, reversed));
        std::vector<size_t> rank(index.size());
        for (size_t k = 0; k < order.voxels().size(); ++k) {
            rank[order.voxels()[k]] = reversed ? order.voxels().size() - 1 - k : k;
        }
        auto ahead = [&](const Coord& p, const Coord& q) {   // q ahead of p along sigma
            for (int a = 0; a < 3; ++a) {
                const int d = q[a] - p[a];
                if (d != 0 && (sigma[a] == 0 || (d > 0) != (sigma[a] > 0))) return false;
            }
            return p != q;
        };
        size_t pairs = 0;
        for (size_t i = 0; i < index.size(); ++i) {
            for (size_t j = 0; j < index.size(); ++j) {
                if (ahead(index.coord(i), index.coord(j))) {
                    ++pairs;
                    ASSERT_LT(rank[i], rank[j]) << "sigma " << sigma << ": " << index.coord(i)
                                                << " must come before " << index.coord(j);
                }
            }
        }
        EXPECT_GT(pairs, 300u) << "the check must exercise many pairs for " << sigma;
    }
}

TEST(LeafOrder, VisitsEveryLineInItsOrderAlongTheLine)
{
    // Restricted to one line, the visiting order must equal the order along the line
    // (LinePartition::position, which increases with sigma . x). Naive lines are monotone
    // 26-paths, so this holds exactly. Standard lines can hold 2x2 blocks (LinePartition.h) whose
    // two middle voxels are incomparable: there the lexicographic order may disagree with the
    // line order -- the "bubbles" of thesis §4.3.3.5. Count them and check that every inversion
    // is such a pair.
    const VoxelIndex index = randomSet(5, 20000, -40, 40);
    std::mt19937 rng(9);
    std::uniform_int_distribution<int> comp(-6, 6);
    size_t directions = 0, bubbles = 0;
    while (directions < 40) {
        const Coord sigma(comp(rng), comp(rng), comp(rng));
        if (sigma == Coord(0)) continue;
        const int g = std::gcd(std::gcd(std::abs(sigma.x()), std::abs(sigma.y())),
            std::abs(sigma.z()));
        if (g != 1) continue;
        ++directions;
        bool reversed = false;
        const LeafOrder order(index, LeafOrder::baseSigns(sigma, reversed));
        for (LineType type : {LineType::Naive, LineType::Standard}) {
            const LinePartition lines(sigma, type);
            std::unordered_map<LineKey, Coord, LineKeyHash> last;
            for (size_t k = 0; k < order.voxels().size(); ++k) {
                const uint32_t v = order.voxels()[reversed ? order.voxels().size() - 1 - k : k];
                const Coord c = index.coord(v);
                auto it = last.find(lines.key(c));
                if (it != last.end() && lines.position(c) <= lines.position(it->second)) {
                    ASSERT_EQ(type, LineType::Standard) << "naive line out of order, sigma "
                                                        << sigma;
                    // Only the incomparable middle of a 2x2 block may come out of order: the
                    // two voxels differ by one step on each of the two minor axes, in opposite
                    // senses, with the same major coordinate.
                    const Coord d = lines.canonical(c) - lines.canonical(it->second);
                    EXPECT_EQ(d[0], 0) << sigma;
                    EXPECT_EQ(std::abs(d[1]) + std::abs(d[2]), 2) << sigma;
                    EXPECT_EQ(d[1], -d[2]) << sigma;
                    ++bubbles;
                }
                last[lines.key(c)] = c;
            }
        }
    }
    std::cout << "standard-line bubbles over " << directions << " directions: " << bubbles << "\n";
}
