// Tests of DirectionSet (vdbrad/sweep/DirectionSet.h): the sweep directions of the line-partition method
// and their direction factors (thesis §4.1.2.2, §4.3.4).
//
// References are re-derived here independently of the implementation: a brute-force scan of the
// whole cube [-R, R]³ for the boundary surfels (instead of the library's shell enumeration), the
// closed-form solid angle of an axis-aligned rectangle (corner arctangents, instead of the
// library's Van Oosterom–Strackee triangles), a voxel-walking ray caster for a Monte-Carlo check,
// and quadrature identities (∫ |cos| dω / 2π = 1).

#include "vdbrad/cloud/HarmonicQuadrature.h"
#include "vdbrad/cloud/PhaseFunction.h"
#include "vdbrad/core/Constants.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/sweep/RealHarmonics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <map>
#include <numeric>
#include <set>
#include <vector>

namespace {

using vdbrad::kPi;

using vdbrad::DirectionSet;
using openvdb::math::Coord;
using openvdb::math::Vec3d;


// ---- independent helpers ----------------------------------------------------------------------

int64_t
norm2(const Coord& p)
{
    return int64_t(p.x()) * p.x() + int64_t(p.y()) * p.y() + int64_t(p.z()) * p.z();
}

Coord
canonicalPrimitive(const Coord& p)
{
    int g = std::abs(p.x());
    g = std::gcd(g, std::abs(p.y()));
    g = std::gcd(g, std::abs(p.z()));
    Coord d(p.x() / g, p.y() / g, p.z() / g);
    const int first = d.x() != 0 ? d.x() : d.y() != 0 ? d.y() : d.z();
    return first < 0 ? Coord(-d.x(), -d.y(), -d.z()) : d;
}

/// Exact solid angle of the rectangle [u1,u2]×[v1,v2] in a plane at distance d > 0 from the eye,
/// by inclusion–exclusion of the corner rectangles anchored at the foot of the perpendicular:
/// Ω(0..x, 0..y) = atan(xy / (d√(x²+y²+d²))), odd in x and in y.
double
rectangleSolidAngle(double u1, double u2, double v1, double v2, double d)
{
    auto f = [d](double x, double y) {
        return std::atan(x * y / (d * std::sqrt(x * x + y * y + d * d)));
    };
    return f(u2, v2) - f(u1, v2) - f(u2, v1) + f(u1, v1);
}

struct BruteForce
{
    std::map<Coord, double> pairOmega; // canonical primitive direction -> Ω of σ and −σ (sr)
    double minSurfelOmega = 1e300;     // smallest signed surfel solid angle (sr)
    double totalOmega = 0.0;           // Σ of all signed surfel solid angles (sr)
};

/// Every voxel of [-R, R]³ in B_R = {|p|² ≤ R²}, every face towards a voxel outside it.
BruteForce
bruteForce(int radius)
{
    const int64_t r2 = int64_t(radius) * radius;
    BruteForce out;
    long double total = 0.0L;
    for (int x = -radius; x <= radius; ++x) {
        for (int y = -radius; y <= radius; ++y) {
            for (int z = -radius; z <= radius; ++z) {
                const Coord p(x, y, z);
                if (norm2(p) > r2) continue;
                for (int m = 0; m < 3; ++m) {
                    for (int s = -1; s <= 1; s += 2) {
                        Coord q = p;
                        q[m] += s;
                        if (norm2(q) <= r2) continue;
                        const double w = p[m] + 0.5 * s; // plane of the face
                        const int a = (m + 1) % 3, b = (m + 2) % 3;
                        const double omega = rectangleSolidAngle(p[a] - 0.5, p[a] + 0.5,
                            p[b] - 0.5, p[b] + 0.5, std::abs(w));
                        // Positive when the outward normal s·e_m points away from the origin.
                        const double signedOmega = (s * w > 0.0) ? omega : -omega;
                        out.minSurfelOmega = std::min(out.minSurfelOmega, signedOmega);
                        total += signedOmega;
                        out.pairOmega[canonicalPrimitive(p)] += signedOmega;
                    }
                }
            }
        }
    }
    out.totalOmega = double(total);
    return out;
}

/// splitmix64, written out again so the tests do not depend on the library's generator.
struct Rng
{
    uint64_t state;
    uint64_t next()
    {
        uint64_t z = (state += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    double uniform() { return double(next() >> 11) * 0x1.0p-53; } // [0, 1)
    /// Uniform on the unit sphere: rejection from the cube (no std:: distributions).
    Vec3d unitVector()
    {
        for (;;) {
            const Vec3d v(2 * uniform() - 1, 2 * uniform() - 1, 2 * uniform() - 1);
            const double l2 = v.lengthSqr();
            if (l2 > 1e-6 && l2 <= 1.0) return v / std::sqrt(l2);
        }
    }
};

std::vector<Vec3d>
randomNormals(size_t n, uint64_t seed)
{
    Rng rng{seed};
    std::vector<Vec3d> normals(n);
    for (Vec3d& v : normals) v = rng.unitVector();
    return normals;
}

double
sumOfFactors(const DirectionSet& set)
{
    long double sum = 0.0L; // long double: the test must not add its own rounding to 1e-12
    for (size_t k = 0; k < set.size(); ++k) sum += set.factor(k);
    return double(sum);
}

bool
isPermutation(const std::vector<size_t>& order, size_t n)
{
    if (order.size() != n) return false;
    std::vector<size_t> sorted = order;
    std::sort(sorted.begin(), sorted.end());
    for (size_t i = 0; i < n; ++i) {
        if (sorted[i] != i) return false;
    }
    return true;
}

// ---- tests ------------------------------------------------------------------------------------

TEST(DirectionSet, SmallRadiusCounts)
{
    // B_1 is the 7-voxel cross: only the 6 axis voxels have exposed faces, 3 pairs. The counts for
    // R = 2, 3 come from the brute-force scan below (and were checked by hand for R = 2: the 6 axis
    // voxels (±2,0,0).., the 12 (±1,±1,0).., the 8 (±1,±1,±1): 26 voxels, 13 pairs).
    const std::array<size_t, 3> expected = {3, 13, 45};
    for (int r = 1; r <= 3; ++r) {
        EXPECT_EQ(bruteForce(r).pairOmega.size(), expected[r - 1]) << "R = " << r;
        EXPECT_EQ(DirectionSet::fromRadius(r).size(), expected[r - 1]) << "R = " << r;
        EXPECT_EQ(DirectionSet::countForRadius(r), expected[r - 1]) << "R = " << r;
    }
    const DirectionSet one = DirectionSet::fromRadius(1);
    EXPECT_EQ(one.direction(0), Coord(0, 0, 1));
    EXPECT_EQ(one.direction(1), Coord(0, 1, 0));
    EXPECT_EQ(one.direction(2), Coord(1, 0, 0));
    for (size_t k = 0; k < 3; ++k) {
        // Each axis pair of B_1 owns the 5 faces of (±1,0,0)...: by symmetry 4π/3 per pair, so
        // A = (4π/3)/(2π) = 2/3; 1e-14 = a few ulps.
        EXPECT_NEAR(one.factor(k), 2.0 / 3.0, 1e-14);
    }
}

TEST(DirectionSet, PrimitiveAndUnique)
{
    for (int r = 1; r <= 30; ++r) {
        const DirectionSet set = DirectionSet::fromRadius(r);
        ASSERT_EQ(set.radius(), r);
        std::set<Coord> seen;
        for (size_t k = 0; k < set.size(); ++k) {
            const Coord& d = set.direction(k);
            ASSERT_EQ(std::gcd(std::gcd(std::abs(d.x()), std::abs(d.y())), std::abs(d.z())), 1)
                << d << " at R = " << r;
            ASSERT_EQ(canonicalPrimitive(d), d) << "not canonical: " << d;
            ASSERT_TRUE(seen.insert(d).second) << "duplicate " << d;
            // Its opposite, canonical or not, is never stored separately.
            ASSERT_EQ(seen.count(Coord(-d.x(), -d.y(), -d.z())), 0u) << "± duplicate " << d;
            // unit(k) is direction(k) normalised; 1e-15 = rounding of a unit vector.
            const Vec3d u = set.unit(k);
            EXPECT_NEAR(u.length(), 1.0, 1e-15);
            EXPECT_NEAR(u.cross(Vec3d(d.x(), d.y(), d.z())).length(), 0.0, 1e-12);
            EXPECT_GT(u.dot(Vec3d(d.x(), d.y(), d.z())), 0.0);
            if (k > 0) {
                EXPECT_TRUE(set.direction(k - 1) < d) << "not lexicographically sorted";
            }
        }
    }
}

TEST(DirectionSet, MatchesBruteForceSurfels)
{
    for (int r = 1; r <= 14; ++r) {
        const BruteForce ref = bruteForce(r);
        const DirectionSet set = DirectionSet::fromRadius(r);
        // Every surfel faces away from the origin (proof in DirectionSet.cc): no negative or null
        // solid angle exists, hence no pair factor can be negative.
        EXPECT_GT(ref.minSurfelOmega, 0.0) << "R = " << r;
        // The closed surface around the origin: Σ signed Ω = 4π; 1e-12 covers the
        // inclusion–exclusion rounding of a few thousand surfels.
        EXPECT_NEAR(ref.totalOmega, 4.0 * kPi, 1e-12) << "R = " << r;
        ASSERT_EQ(set.size(), ref.pairOmega.size()) << "R = " << r;
        for (size_t k = 0; k < set.size(); ++k) {
            const auto it = ref.pairOmega.find(set.direction(k));
            ASSERT_NE(it, ref.pairOmega.end()) << set.direction(k) << " at R = " << r;
            // A = Ω_pair / (2π) with Ω_pair from the rectangle formula; 1e-13 ≫ the ~1e-16 error
            // of either formula, ≪ the smallest factor (~1e-4 at R = 14).
            EXPECT_NEAR(set.factor(k), it->second / (2.0 * kPi), 1e-13) << set.direction(k);
        }
    }
}

// cellOf (Sky::cellMeans' cells): the surfel a ray from the origin crosses, found by testing
// the ray against every boundary surfel of B_R, and the cells' measured areas against the
// surfels' exact solid angles.
TEST(DirectionSet, CellOfIsTheSurfelTheRayCrosses)
{
    for (const int r : {1, 3, 6}) {
        const DirectionSet set = DirectionSet::fromRadius(r);
        const int64_t r2 = int64_t(r) * r;
        Rng rng{uint64_t(77 + r)};
        for (int t = 0; t < 3000; ++t) {
            const Vec3d d = rng.unitVector();
            // The face (of a voxel inside, towards one outside) whose square the ray meets.
            Coord owner;
            int crossed = 0;
            for (int x = -r; x <= r; ++x) {
                for (int y = -r; y <= r; ++y) {
                    for (int z = -r; z <= r; ++z) {
                        const Coord p(x, y, z);
                        if (norm2(p) > r2) continue;
                        for (int m = 0; m < 3; ++m) {
                            for (int sgn = -1; sgn <= 1; sgn += 2) {
                                Coord q = p;
                                q[m] += sgn;
                                if (norm2(q) <= r2) continue;
                                const double w = p[m] + 0.5 * sgn;
                                if (d[m] == 0.0 || w / d[m] <= 0.0) continue;
                                const Vec3d hit = d * (w / d[m]);
                                const int a = (m + 1) % 3, b = (m + 2) % 3;
                                if (std::abs(hit[a] - p[a]) <= 0.5 && std::abs(hit[b] - p[b]) <= 0.5) {
                                    owner = p;
                                    ++crossed;
                                }
                            }
                        }
                    }
                }
            }
            ASSERT_EQ(crossed, 1) << d << " at R = " << r;   // random rays miss the edges
            const int g = std::gcd(std::gcd(std::abs(owner.x()), std::abs(owner.y())),
                std::abs(owner.z()));
            const Coord primitive(owner.x() / g, owner.y() / g, owner.z() / g);
            const Coord sigma = canonicalPrimitive(owner);
            const bool negative = primitive != sigma;
            size_t k = 0;
            while (k < set.size() && set.direction(k) != sigma) ++k;
            ASSERT_LT(k, set.size());
            EXPECT_EQ(set.cellOf(d), 2 * k + (negative ? 1 : 0)) << d << " at R = " << r;
        }
    }
    // Areas: 400,000 random directions; each cell's share times 4 pi against its solid angle
    // pi A (binomial: within 5 standard deviations).
    const DirectionSet set = DirectionSet::fromRadius(5);
    std::vector<size_t> count(2 * set.size(), 0);
    Rng rng{5};
    const size_t samples = 400000;
    for (size_t t = 0; t < samples; ++t) ++count[set.cellOf(rng.unitVector())];
    for (size_t c = 0; c < count.size(); ++c) {
        const double p = kPi * set.factor(c / 2) / (4.0 * kPi);
        const double sd = std::sqrt(p * (1.0 - p) / double(samples));
        EXPECT_NEAR(double(count[c]) / double(samples), p, 5.0 * sd) << "cell " << c;
    }
    EXPECT_THROW(set.cellOf(Vec3d(0.0)), openvdb::ValueError);
}

TEST(DirectionSet, FactorsSumToTwoAndArePositive)
{
    for (int r : {1, 2, 3, 5, 8, 16, 32, 64, 100, 400}) {
        const DirectionSet set = DirectionSet::fromRadius(r);
        // Σ_pairs Ω_pair = 4π exactly, so Σ A = 4π/(2π) = 2; 1e-12 as required (the sum has up to
        // a million terms, each with a relative error of a few ulps).
        EXPECT_NEAR(sumOfFactors(set), 2.0, 1e-12) << "R = " << r;
        double minFactor = 1e300;
        for (size_t k = 0; k < set.size(); ++k) minFactor = std::min(minFactor, set.factor(k));
        EXPECT_GT(minFactor, 0.0) << "R = " << r;
    }
}

TEST(DirectionSet, HemisphereSum)
{
    const std::vector<Vec3d> normals = randomNormals(10000, 0x5EED0001ull);
    // Upper bounds on max |hemisphereSum − 1|: the measured values (printed below; R = 4: 0.0139,
    // 8: 0.0049, 16: 0.0023, 32: 0.0012, i.e. about 0.037 / R: each pair's cosine is taken at σ̂,
    // which is not the centroid of its solid angle) times 1.5. A wrong normalisation (factor 2)
    // or a wrong set of surfels would exceed them by far.
    const std::map<int, double> bound = {{4, 0.021}, {8, 0.0075}, {16, 0.0035}, {32, 0.0018}};
    double previous = 1e300;
    std::cout << "   R   pairs   sum(A)-2     max|hemisphereSum-1| (10000 normals)\n";
    for (const auto& [r, maxAllowed] : bound) {
        const DirectionSet set = DirectionSet::fromRadius(r);
        double maxError = 0.0, maxWeightError = 0.0;
        for (const Vec3d& n : normals) {
            const double raw = set.hemisphereSum(n);
            maxError = std::max(maxError, std::abs(raw - 1.0));
            const std::vector<double> w = set.normalisedWeights(n);
            double sum = 0.0;
            for (double x : w) sum += x;
            maxWeightError = std::max(maxWeightError, std::abs(sum - 1.0));
        }
        std::cout << std::setw(4) << r << std::setw(8) << set.size() << "   "
                  << std::scientific << std::setprecision(2) << std::setw(10)
                  << sumOfFactors(set) - 2.0 << "   " << std::defaultfloat << std::setprecision(4)
                  << maxError << "\n";
        EXPECT_LT(maxError, maxAllowed) << "R = " << r;
        EXPECT_LT(maxError, previous) << "R = " << r << " is not better than the radius before";
        previous = maxError;
        // Normalised weights add up to 1: the requirement is 1e-6 (the actual error is
        // the rounding of a few thousand additions, ~1e-14).
        EXPECT_LT(maxWeightError, 1e-6) << "R = " << r;
    }
    std::cout << std::setprecision(6);

    // The weights are |σ̂·n| A / Σ, in index order, for any scale of n.
    const DirectionSet set = DirectionSet::fromRadius(5);
    const Vec3d n = Vec3d(0.3, -0.5, 0.81).unit();
    const std::vector<double> w = set.normalisedWeights(3.0 * n);
    const double sum = set.hemisphereSum(n);
    ASSERT_EQ(w.size(), set.size());
    for (size_t k = 0; k < set.size(); ++k) {
        EXPECT_NEAR(w[k], std::abs(set.unit(k).dot(n)) * set.factor(k) / sum, 1e-15);
    }
    EXPECT_THROW(set.normalisedWeights(Vec3d(0.0)), openvdb::ValueError);
    EXPECT_THROW(DirectionSet().normalisedWeights(n), openvdb::ValueError);
}

TEST(DirectionSet, AxisPermutationSymmetry)
{
    for (int r : {3, 7, 12}) {
        const DirectionSet set = DirectionSet::fromRadius(r);
        std::map<Coord, double> factorOf;
        for (size_t k = 0; k < set.size(); ++k) factorOf[set.direction(k)] = set.factor(k);
        const std::array<std::array<int, 3>, 6> perms = {
            {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
        int transforms = 0;
        for (const auto& perm : perms) {
            for (int signs = 0; signs < 8; ++signs) {
                ++transforms;
                for (size_t k = 0; k < set.size(); ++k) {
                    const Coord& d = set.direction(k);
                    Coord t;
                    for (int i = 0; i < 3; ++i) t[i] = ((signs >> i) & 1 ? -1 : 1) * d[perm[i]];
                    const auto it = factorOf.find(canonicalPrimitive(t));
                    ASSERT_NE(it, factorOf.end()) << d << " -> " << t << " at R = " << r;
                    // Same surfels up to the isometry; 1e-12 ≫ rounding (~1e-18 here).
                    EXPECT_NEAR(it->second, set.factor(k), 1e-12) << d << " -> " << t;
                }
            }
        }
        EXPECT_EQ(transforms, 48);
    }
}

TEST(DirectionSet, CountForRadius)
{
    // Cross-check of the orbit-counting formula against the construction.
    for (int r = 1; r <= 60; ++r) {
        EXPECT_EQ(DirectionSet::countForRadius(r), DirectionSet::fromRadius(r).size())
            << "R = " << r;
    }
    for (int r : {100, 173, 400}) {
        EXPECT_EQ(DirectionSet::countForRadius(r), DirectionSet::fromRadius(r).size());
    }
    EXPECT_EQ(DirectionSet::maxCount(), DirectionSet::countForRadius(DirectionSet::kMaxRadius));
    // Strictly increasing: "nearest count" and "nearest radius" then agree.
    for (int r = 2; r <= DirectionSet::kMaxRadius; ++r) {
        EXPECT_LT(DirectionSet::countForRadius(r - 1), DirectionSet::countForRadius(r));
    }
    EXPECT_THROW(DirectionSet::countForRadius(0), openvdb::ValueError);
    EXPECT_THROW(DirectionSet::countForRadius(DirectionSet::kMaxRadius + 1),
        openvdb::ValueError);
}

TEST(DirectionSet, FromCount)
{
    // Brute force over R with the sets themselves (R ≤ 40 covers N up to ~10^4).
    std::vector<size_t> counts(41, 0);
    for (int r = 1; r <= 40; ++r) counts[r] = DirectionSet::fromRadius(r).size();
    for (int n = 1; n <= int(counts[40]) - 200; n += (n < 200 ? 1 : 37)) {
        int best = 1;
        for (int r = 2; r <= 40; ++r) {
            const long dr = std::labs(long(counts[r]) - n), db = std::labs(long(counts[best]) - n);
            if (dr < db) best = r; // strict: ties keep the smaller radius
        }
        const DirectionSet set = DirectionSet::fromCount(n);
        EXPECT_EQ(set.radius(), best) << "N = " << n;
        EXPECT_EQ(set.size(), counts[best]) << "N = " << n;
    }
    // A tie: halfway between the counts of R = 2 (13) and R = 3 (45) goes to R = 2.
    EXPECT_EQ(DirectionSet::fromCount(29).radius(), 2);
    EXPECT_EQ(DirectionSet::fromCount(30).radius(), 3);
    // Largest accepted count.
    EXPECT_EQ(DirectionSet::fromCount(int(DirectionSet::maxCount())).radius(),
        DirectionSet::kMaxRadius);

    EXPECT_THROW(DirectionSet::fromCount(0), openvdb::ValueError);
    EXPECT_THROW(DirectionSet::fromCount(-5), openvdb::ValueError);
    EXPECT_THROW(DirectionSet::fromCount(int(DirectionSet::maxCount()) + 1), openvdb::ValueError);
    EXPECT_THROW(DirectionSet::fromRadius(0), openvdb::ValueError);
    EXPECT_THROW(DirectionSet::fromRadius(-1), openvdb::ValueError);
    EXPECT_THROW(DirectionSet::fromRadius(DirectionSet::kMaxRadius + 1), openvdb::ValueError);
}

TEST(DirectionSet, ProgressiveOrder)
{
    const int radius = 16;
    const DirectionSet set = DirectionSet::fromRadius(radius);
    const std::vector<size_t> order = set.progressiveOrder();
    ASSERT_TRUE(isPermutation(order, set.size()));

    std::set<Coord> axes = {Coord(1, 0, 0), Coord(0, 1, 0), Coord(0, 0, 1)};
    std::set<Coord> firstThree;
    for (size_t i = 0; i < 3; ++i) firstThree.insert(set.direction(order[i]));
    EXPECT_EQ(firstThree, axes);

    // Reference appearance radius: the first r whose brute-force boundary has the direction.
    std::map<Coord, int> firstSeen;
    for (int r = 1; r <= radius; ++r) {
        for (const auto& entry : bruteForce(r).pairOmega) firstSeen.emplace(entry.first, r);
    }
    for (size_t i = 0; i < order.size(); ++i) {
        const size_t k = order[i];
        ASSERT_EQ(set.appearanceRadius(k), firstSeen.at(set.direction(k))) << set.direction(k);
        if (i > 0) {
            const size_t prev = order[i - 1];
            ASSERT_LE(set.appearanceRadius(prev), set.appearanceRadius(k));
            if (set.appearanceRadius(prev) == set.appearanceRadius(k)) {
                ASSERT_LE(norm2(set.direction(prev)), norm2(set.direction(k)));
            }
        }
    }
    // Deterministic.
    EXPECT_EQ(order, set.progressiveOrder());
}

TEST(DirectionSet, ShuffledOrder)
{
    const DirectionSet set = DirectionSet::fromRadius(10);
    const std::vector<size_t> a = set.shuffledOrder(42), b = set.shuffledOrder(42),
                              c = set.shuffledOrder(43);
    EXPECT_TRUE(isPermutation(a, set.size()));
    EXPECT_TRUE(isPermutation(c, set.size()));
    EXPECT_EQ(a, b);
    EXPECT_NE(a, c);
    std::vector<size_t> identity(set.size());
    std::iota(identity.begin(), identity.end(), size_t(0));
    EXPECT_NE(a, identity);
    EXPECT_TRUE(DirectionSet().shuffledOrder(1).empty());
    EXPECT_EQ(DirectionSet::fromRadius(1).shuffledOrder(7).size(), 3u);
}

TEST(DirectionSet, MonteCarloSolidAngles)
{
    // Walk 200 000 random rays voxel by voxel from the origin (the centre of voxel 0) and credit
    // each to the primitive direction of the last voxel of B_R before it first leaves the ball.
    // The expected fraction for a pair is Ω_pair / 4π = A / 2.
    const int radius = 3;
    const int64_t r2 = int64_t(radius) * radius;
    const size_t samples = 200000;
    const DirectionSet set = DirectionSet::fromRadius(radius);
    std::map<Coord, size_t> hits;
    Rng rng{0xC0FFEEull};
    for (size_t i = 0; i < samples; ++i) {
        const Vec3d d = rng.unitVector();
        Coord p(0, 0, 0), step;
        Vec3d tMax, tDelta;
        for (int a = 0; a < 3; ++a) {
            step[a] = d[a] >= 0.0 ? 1 : -1;
            tDelta[a] = d[a] != 0.0 ? 1.0 / std::abs(d[a]) : 1e300;
            tMax[a] = 0.5 * tDelta[a]; // the cube of voxel 0 ends at ±1/2
        }
        for (;;) {
            const int a = tMax[0] < tMax[1] ? (tMax[0] < tMax[2] ? 0 : 2)
                                            : (tMax[1] < tMax[2] ? 1 : 2);
            Coord next = p;
            next[a] += step[a];
            if (norm2(next) > r2) break;
            p = next;
            tMax[a] += tDelta[a];
        }
        ++hits[canonicalPrimitive(p)];
    }
    EXPECT_EQ(hits.size(), set.size());
    for (size_t k = 0; k < set.size(); ++k) {
        const double expected = set.factor(k) / 2.0;
        const double observed = double(hits[set.direction(k)]) / samples;
        // 4 standard errors of a binomial proportion (fixed seed, so deterministic).
        const double sigma = std::sqrt(expected * (1.0 - expected) / samples);
        EXPECT_NEAR(observed, expected, 4.0 * sigma) << set.direction(k);
    }
}

TEST(DirectionSet, BuildWorkGrowsAsRSquared)
{
    // fromRadius reads the set off the boundary shell (fact (3) of DirectionSet.cc): one candidate
    // column per (axis, a, b) with a² + b² ≤ R², each giving at most one exposed voxel per sign,
    // so its work and its output are O(R²), where scanning the ball would be O(R³). Checked by
    // counting, not timing (the build time is measured by benchmarks/bench_directions.cc): the
    // pairs never exceed the candidate columns, counted here independently (lattice points of the
    // disc of radius R, three axes), and they quadruple when R doubles (an O(R³) set would grow
    // 8×; counted: 4.04, 4.03, 4.01 from R = 25 to 200, the O(R) boundary terms fading).
    auto discPoints = [](int r) {
        size_t n = 0;
        for (int a = -r; a <= r; ++a) {
            for (int b = -r; b <= r; ++b) n += int64_t(a) * a + int64_t(b) * b <= int64_t(r) * r;
        }
        return n;
    };
    size_t previous = 0;
    for (int r : {25, 50, 100, 200}) {
        const size_t pairs = DirectionSet::fromRadius(r).size();
        EXPECT_LE(pairs, 3 * discPoints(r)) << "R = " << r;
        if (previous > 0) {
            const double growth = double(pairs) / double(previous);
            EXPECT_GT(growth, 3.9) << "R = " << r;
            EXPECT_LT(growth, 4.1) << "R = " << r;
        }
        previous = pairs;
    }
    EXPECT_EQ(DirectionSet::fromRadius(100).size(), 51867u);   // the header's figure
}

} // namespace

namespace {

// max over l <= degree, all m, of |sum over both senses of Omega Y_lm - int Y_lm| for the pair
// factors @a factors of @a set (Omega = pi A per sense), summed here independently of the fit.
double
harmonicQuadratureError(const DirectionSet& set, const std::vector<double>& factors, int degree)
{
    const double pi = 3.14159265358979323846;
    const size_t M = size_t(degree + 1) * size_t(degree + 1);
    std::vector<double> sum(M, 0.0), y(M);
    for (size_t k = 0; k < set.size(); ++k) {
        for (double sense : {1.0, -1.0}) {
            vdbrad::realSphericalHarmonics(degree, sense * set.unit(k), y.data());
            for (size_t lm = 0; lm < M; ++lm) sum[lm] += pi * factors[k] * y[lm];
        }
    }
    double worst = std::abs(sum[0] - std::sqrt(4.0 * pi));
    for (size_t lm = 1; lm < M; ++lm) worst = std::max(worst, std::abs(sum[lm]));
    return worst;
}

} // namespace

TEST(HarmonicQuadrature, ExactToTwiceTheDefaultPhaseOrderWithPositiveWeights)
{
    // The default cloud set (303 pairs) and order 8: the cells' solid angles integrate
    // harmonics to degree 16 only to ~1e-1 (measured 0.13); the fitted weights to rounding,
    // each within [1/4, 4] of its cell, the same for directions the cube's isometries exchange.
    const DirectionSet set = DirectionSet::fromCount(300);
    ASSERT_EQ(set.size(), 303u);
    std::vector<double> cells(set.size());
    for (size_t k = 0; k < set.size(); ++k) cells[k] = set.factor(k);
    const double before = harmonicQuadratureError(set, cells, 16);
    std::printf("cells' error to degree 16: %.3g\n", before);
    EXPECT_GT(before, 1e-2);
    const vdbrad::HarmonicQuadrature q = vdbrad::fitHarmonicQuadrature(set, 16);
    ASSERT_EQ(q.degree, 16);
    ASSERT_EQ(q.factors.size(), set.size());
    EXPECT_LT(harmonicQuadratureError(set, q.factors, 16), 1e-12);
    EXPECT_LT(q.residual, 1e-12);
    double sum = 0.0;
    std::map<Coord, double> factorOf;
    for (size_t k = 0; k < set.size(); ++k) {
        EXPECT_GT(q.factors[k], 0.25 * set.factor(k)) << set.direction(k);
        EXPECT_LT(q.factors[k], 4.0 * set.factor(k)) << set.direction(k);
        sum += q.factors[k];
        factorOf[set.direction(k)] = q.factors[k];
    }
    EXPECT_NEAR(sum, 2.0, 1e-12);
    // The minimum-norm fit of a symmetric problem is symmetric: swapping and mirroring axes
    // maps the set onto itself, so equivalent directions keep equal weights.
    for (size_t k = 0; k < set.size(); ++k) {
        const Coord& d = set.direction(k);
        for (const Coord& t : {Coord(d[1], d[0], d[2]), Coord(d[2], d[1], -d[0])}) {
            EXPECT_NEAR(factorOf.at(canonicalPrimitive(t)), q.factors[k], 1e-12) << d << " " << t;
        }
    }
    // The set with those weights: the same directions, the fitted factors.
    const DirectionSet fitted = set.withFactors(q.factors);
    EXPECT_EQ(fitted.direction(7), set.direction(7));
    EXPECT_EQ(fitted.factor(7), q.factors[7]);
    EXPECT_THROW(set.withFactors(std::vector<double>(3, 2.0 / 3.0)), openvdb::ValueError);
    std::vector<double> negative = q.factors;
    negative[0] = -negative[0];
    negative[1] += 2.0 * q.factors[0];
    EXPECT_THROW(set.withFactors(negative), openvdb::ValueError);
}

TEST(HarmonicQuadrature, SmallSetsFitTheHighestDegreeTheyCan)
{
    // The 3 axis pairs (R 1) hold no constraint beyond the sum (the cells are kept: degree 0);
    // 13 pairs (R 2) hold the 6 even harmonics of degree 2 but not the 15 of degree 4; a degree
    // asked below what fits is what is fitted.
    for (const auto& [radius, asked, expected] :
        std::vector<std::array<int, 3>>{{1, 16, 0}, {2, 16, 2}, {5, 4, 4}}) {
        const DirectionSet set = DirectionSet::fromRadius(radius);
        const vdbrad::HarmonicQuadrature q = vdbrad::fitHarmonicQuadrature(set, asked);
        std::printf("R %d (%zu pairs), degree %d asked: %d fitted\n", radius, set.size(), asked,
            q.degree);
        EXPECT_EQ(q.degree, expected) << radius;
        EXPECT_LT(harmonicQuadratureError(set, q.factors, q.degree), 1e-12) << radius;
        for (size_t k = 0; k < set.size(); ++k) EXPECT_GT(q.factors[k], 0.25 * set.factor(k));
    }
}
