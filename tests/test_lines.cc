// LinePartition: the partition of Z^3 into naive / standard 3D arithmetic lines of one direction
// (thesis §4.3.2-4.3.3, Figueiredo & Reveillès 1995), checked against an independent reference
// written straight from the defining inequalities, by brute force over boxes and along long walks.
#include "vdbrad/sweep/LinePartition.h"

#include <openvdb/Types.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <vector>

using vdbrad::LineKey;
using vdbrad::LinePartition;
using vdbrad::LineType;
using openvdb::Coord;
using openvdb::CoordBBox;

namespace vdbrad {
// Readable failure messages for keys.
void PrintTo(const LineKey& k, std::ostream* os) { *os << "(" << k.i << ", " << k.j << ")"; }
} // namespace vdbrad

namespace {

using I64 = int64_t;
using V3 = std::array<I64, 3>;

const LineType kTypes[] = {LineType::Naive, LineType::Standard};

const char* typeName(LineType t) { return t == LineType::Naive ? "naive" : "standard"; }

// floor / ceil through long double. Exact for |n| <= 2^53 and d >= 1: n is representable, and a
// non-integer n/d is at least 1/d from an integer, a relative gap >= 1/|n| >= 2^-53, wider than
// long double's rounding (2^-64 relative on x86, 2^-113 on aarch64), so rounding never reaches
// the integer. Every numerator below is <= 2 * 2^20 * 2^31 = 2^52.
I64 floorRef(I64 n, I64 d) { return I64(std::floor((long double)n / (long double)d)); }
I64 ceilRef(I64 n, I64 d) { return I64(std::ceil((long double)n / (long double)d)); }

// The definition, independently of LinePartition's folded multipliers: axes sorted by decreasing
// |sigma_k| with std::stable_sort (ties keep axis order), negative components flipped, then
// i w_ab <= -b x' + a y' < (i + 1) w_ab and j w_ac <= -c x' + a z' < (j + 1) w_ac.
struct Reference
{
    std::array<int, 3> perm{{0, 1, 2}};
    std::array<I64, 3> sign{};
    I64 a, b, c, wab, wac;

    Reference(const Coord& s, LineType t)
    {
        std::stable_sort(perm.begin(), perm.end(),
            [&](int u, int v) { return std::llabs(s[u]) > std::llabs(s[v]); });
        for (int k = 0; k < 3; ++k) sign[k] = s[k] < 0 ? -1 : 1;
        a = std::llabs(s[perm[0]]);
        b = std::llabs(s[perm[1]]);
        c = std::llabs(s[perm[2]]);
        wab = t == LineType::Naive ? a : a + b;
        wac = t == LineType::Naive ? a : a + c;
    }
    V3 canon(const Coord& v) const
    {
        V3 q;
        for (int n = 0; n < 3; ++n) q[n] = sign[perm[n]] * I64(v[perm[n]]);
        return q;
    }
    Coord orig(const V3& q) const
    {
        Coord v;
        for (int n = 0; n < 3; ++n) v[perm[n]] = int32_t(sign[perm[n]] * q[n]);
        return v;
    }
    LineKey key(const Coord& v) const
    {
        const V3 q = canon(v);
        return LineKey{floorRef(-b * q[0] + a * q[1], wab), floorRef(-c * q[0] + a * q[2], wac)};
    }
    // Closed ranges [lo, hi] of y' (resp. z') on line i (resp. j) at major coordinate x.
    std::pair<I64, I64> yRange(I64 i, I64 x) const
    {
        return {ceilRef(i * wab + b * x, a), ceilRef((i + 1) * wab + b * x, a) - 1};
    }
    std::pair<I64, I64> zRange(I64 j, I64 x) const
    {
        return {ceilRef(j * wac + c * x, a), ceilRef((j + 1) * wac + c * x, a) - 1};
    }
};

bool isPrimitive(const Coord& s)
{
    return std::gcd(std::gcd(std::abs(s[0]), std::abs(s[1])), std::abs(s[2])) == 1;
}

// All axis permutations and sign patterns of @a base (duplicates removed by the caller's set).
void addSymmetries(std::set<std::tuple<int, int, int>>& out, const Coord& base)
{
    std::array<int, 3> p{{0, 1, 2}};
    do {
        for (int m = 0; m < 8; ++m) {
            Coord s;
            for (int n = 0; n < 3; ++n) s[n] = ((m >> n) & 1 ? -1 : 1) * base[p[n]];
            out.insert({s[0], s[1], s[2]});
        }
    } while (std::next_permutation(p.begin(), p.end()));
}

// The test directions: every permutation and sign pattern of a few shapes (distinct components,
// zeros, ties), hand-picked awkward ones, then random primitive ones, small and large.
const std::vector<Coord>& testDirections()
{
    static const std::vector<Coord> dirs = [] {
        std::set<std::tuple<int, int, int>> set;
        for (const Coord& b : {Coord(1, 0, 0), Coord(1, 1, 0), Coord(1, 1, 1), Coord(2, 1, 0),
                 Coord(3, 2, 0), Coord(2, 1, 1), Coord(2, 2, 1), Coord(3, 2, 1), Coord(5, 4, 3),
                 Coord(7, 7, 6)}) {
            addSymmetries(set, b);
        }
        // (6, 10, 15): primitive although no two components are coprime.
        for (const Coord& s : {Coord(6, 10, 15), Coord(-1000, 999, 1), Coord(997, -1000, 3),
                 Coord(1000, 1, 0), Coord(0, -1000, 999), Coord(1000, 1000, 999)}) {
            set.insert({s[0], s[1], s[2]});
        }
        std::mt19937 rng(424242);
        auto addRandom = [&](int count, int range, bool zeroOne) {
            std::uniform_int_distribution<int> comp(-range, range), axis(0, 2);
            for (int added = 0; added < count;) {
                Coord s(comp(rng), comp(rng), comp(rng));
                if (zeroOne) s[axis(rng)] = 0;
                if (s == Coord(0) || !isPrimitive(s)) continue;
                if (set.insert({s[0], s[1], s[2]}).second) ++added;
            }
        };
        addRandom(100, 9, false);
        addRandom(30, 9, true);
        addRandom(30, 1000, false);
        addRandom(10, 1000, true);
        std::vector<Coord> v;
        for (const auto& [x, y, z] : set) v.emplace_back(x, y, z);
        return v;
    }();
    return dirs;
}

// Random voxel: moderate (|.| <= 10^6) or near +-2^30 (room left for walks and +k sigma).
Coord randomVoxel(std::mt19937_64& rng, bool nearLimit)
{
    std::uniform_int_distribution<int32_t> mid(-1000000, 1000000), off(-100000, 100000);
    std::bernoulli_distribution coin;
    Coord v;
    for (int k = 0; k < 3; ++k) {
        v[k] = nearLimit ? (coin(rng) ? 1 : -1) * ((1 << 30) - 200000) + off(rng) : mid(rng);
    }
    return v;
}

// The perpendicular distance from @a v to the Euclidean line through @a v0 along @a s.
long double distanceToLine(const Coord& v, const Coord& v0, const Coord& s)
{
    const long double d[3] = {(long double)v[0] - v0[0], (long double)v[1] - v0[1],
        (long double)v[2] - v0[2]};
    const long double x = d[1] * s[2] - d[2] * s[1], y = d[2] * s[0] - d[0] * s[2],
                      z = d[0] * s[1] - d[1] * s[0];
    return std::sqrt((x * x + y * y + z * z) / ((long double)s.asVec3d().lengthSqr()));
}

// Step from u to v along the line, in original coordinates: every component moves by 0 or 1 in
// the direction of sigma's component (0 where that component is 0).
bool followsSigma(const Coord& u, const Coord& v, const Coord& s)
{
    for (int k = 0; k < 3; ++k) {
        const int d = v[k] - u[k];
        if (d != 0 && d != (s[k] > 0 ? 1 : -1)) return false;
        if (s[k] == 0 && d != 0) return false;
    }
    return true;
}

int l1(const Coord& u, const Coord& v)
{
    return std::abs(v[0] - u[0]) + std::abs(v[1] - u[1]) + std::abs(v[2] - u[2]);
}

// Corner c (0..7, bit k: max along axis k) of @a box.
Coord corner(const CoordBBox& box, int c)
{
    return Coord(c & 1 ? box.max().x() : box.min().x(), c & 2 ? box.max().y() : box.min().y(),
        c & 4 ? box.max().z() : box.min().z());
}

// The s-th test voxel of @a box: its 8 corners, then voxels near its centre (where the centred
// rule moves even numerators, LinePartition::centreOn) up to s = 400, then random ones.
Coord boxSample(std::mt19937& rng, const CoordBBox& box, int s)
{
    if (s < 8) return corner(box, s);
    if (s < 400) {
        std::uniform_int_distribution<int> comp(-12, 12);
        const Coord c = ((box.min() + box.max()) >> 1) + Coord(comp(rng), comp(rng), comp(rng));
        return Coord::maxComponent(box.min(), Coord::minComponent(box.max(), c));
    }
    std::uniform_int_distribution<int> x(box.min().x(), box.max().x()),
        y(box.min().y(), box.max().y()), z(box.min().z(), box.max().z());
    return Coord(x(rng), y(rng), z(rng));
}

// f(sigma, type, box, partition) for @a tries random directions (components in [-12, 12], the
// primitive ones), both line types, and every box, the partition centred on the box.
template<typename F>
void forCentredPartitions(std::mt19937& rng, int tries, const std::vector<CoordBBox>& boxes, F&& f)
{
    std::uniform_int_distribution<int> comp(-12, 12);
    for (int d = 0; d < tries; ++d) {
        const Coord sigma(comp(rng), comp(rng), comp(rng));
        if (sigma == Coord(0)) continue;
        if (std::gcd(std::gcd(std::abs(sigma.x()), std::abs(sigma.y())), std::abs(sigma.z())) != 1) {
            continue;
        }
        for (LineType type : {LineType::Naive, LineType::Standard}) {
            for (const CoordBBox& box : boxes) {
                LinePartition p(sigma, type);
                p.centreOn(box.min() + box.max());
                f(sigma, box, p);
            }
        }
    }
}

// ---- floor division ---------------------------------------------------------------------------

TEST(LinePartition, FloorDivMatchesFloor)
{
    // Exhaustive small range against std::floor (exact there, see floorRef).
    for (I64 d = 1; d <= 64; ++d) {
        for (I64 n = -4000; n <= 4000; ++n) ASSERT_EQ(vdbrad::floorDiv(n, d), floorRef(n, d));
    }
    // Large values: the defining inequality q d <= n < q d + d, in 128-bit to avoid overflow.
    std::mt19937_64 rng(7);
    std::uniform_int_distribution<I64> num(INT64_MIN, INT64_MAX), den(1, I64(1) << 22);
    __extension__ typedef __int128 I128;  // GCC/Clang builtin; __extension__ for -Wpedantic
    auto check = [](I64 n, I64 d) {
        const I128 q = vdbrad::floorDiv(n, d);
        EXPECT_TRUE(q * d <= n && n < q * d + d) << n << " / " << d;
    };
    for (int t = 0; t < 100000; ++t) check(num(rng), den(rng));
    for (I64 d : {I64(1), I64(2), I64(3), I64(1000), I64(2001), INT64_MAX}) {
        for (I64 n : {INT64_MIN, INT64_MIN + 1, I64(-1), I64(0), I64(1), INT64_MAX}) check(n, d);
    }
}

// ---- construction -----------------------------------------------------------------------------

TEST(LinePartition, RejectsZeroNonPrimitiveAndHugeDirections)
{
    for (const Coord& s : {Coord(0, 0, 0), Coord(2, 0, 0), Coord(0, -4, 6), Coord(2, 4, 6),
             Coord(-3, 0, 3), Coord(7, 7, 7), Coord(1000, 0, -1000),
             Coord(LinePartition::kMaxComponent + 1, 1, 0)}) {
        for (LineType t : kTypes) {
            EXPECT_THROW(LinePartition(s, t), openvdb::ValueError) << s;
        }
    }
    // The bound itself is allowed (documented valid range).
    EXPECT_NO_THROW(LinePartition(Coord(LinePartition::kMaxComponent, -1, 0), LineType::Naive));
}

TEST(LinePartition, ReductionOfHandPickedDirections)
{
    struct Case { Coord s; std::array<int, 3> perm, sign; Coord canon; };
    // perm[n] = original axis of canonical axis n; the tie rule puts the lower axis first.
    const Case cases[] = {
        {Coord(1, 0, 0), {0, 1, 2}, {1, 1, 1}, Coord(1, 0, 0)},
        {Coord(0, 0, -1), {2, 0, 1}, {1, 1, -1}, Coord(1, 0, 0)},
        {Coord(1, 1, 0), {0, 1, 2}, {1, 1, 1}, Coord(1, 1, 0)},
        {Coord(0, 1, 1), {1, 2, 0}, {1, 1, 1}, Coord(1, 1, 0)},
        {Coord(3, -2, 0), {0, 1, 2}, {1, -1, 1}, Coord(3, 2, 0)},
        {Coord(-5, 4, -3), {0, 1, 2}, {-1, 1, -1}, Coord(5, 4, 3)},
        {Coord(7, 7, 6), {0, 1, 2}, {1, 1, 1}, Coord(7, 7, 6)},
        {Coord(2, -3, 3), {1, 2, 0}, {1, -1, 1}, Coord(3, 3, 2)},
        {Coord(-1, 2, -4), {2, 1, 0}, {-1, 1, -1}, Coord(4, 2, 1)},
    };
    for (const Case& cs : cases) {
        for (LineType t : kTypes) {
            const LinePartition lp(cs.s, t);
            EXPECT_EQ(lp.permutation(), cs.perm) << cs.s;
            EXPECT_EQ(lp.signs(), cs.sign) << cs.s;
            EXPECT_EQ(lp.canonicalDirection(), cs.canon) << cs.s;
            EXPECT_EQ(lp.majorAxis(), cs.perm[0]);
            EXPECT_EQ(lp.direction(), cs.s);
            EXPECT_EQ(lp.type(), t);
            const int a = cs.canon[0], b = cs.canon[1], c = cs.canon[2];
            EXPECT_EQ(lp.omegaAB(), t == LineType::Naive ? a : a + b);
            EXPECT_EQ(lp.omegaAC(), t == LineType::Naive ? a : a + c);
        }
    }
}

// key(x) for sigma equals key(canonical(x)) for the canonical sigma, for all symmetric variants,
// and both equal the reference formula. 418 directions x 2 types x 200 voxels.
TEST(LinePartition, KeyMatchesReferenceAndCanonicalReduction)
{
    std::mt19937_64 rng(11);
    std::uniform_int_distribution<int32_t> any(INT32_MIN + 1, INT32_MAX);
    for (const Coord& s : testDirections()) {
        for (LineType t : kTypes) {
            const LinePartition lp(s, t);
            const LinePartition canon(lp.canonicalDirection(), t);
            const Reference ref(s, t);
            ASSERT_EQ(canon.permutation(), (std::array<int, 3>{{0, 1, 2}}));
            ASSERT_EQ(canon.signs(), (std::array<int, 3>{{1, 1, 1}}));
            ASSERT_EQ(lp.canonical(s), lp.canonicalDirection()) << s;
            for (int n = 0; n < 3; ++n) ASSERT_EQ(lp.permutation()[n], ref.perm[n]) << s;
            for (int v = 0; v < 200; ++v) {
                // A third of the voxels use the full int32 range (key() is valid there).
                const Coord x = v % 3 == 2 ? Coord(any(rng), any(rng), any(rng))
                                           : randomVoxel(rng, v % 3 == 1);
                const Coord cx = lp.canonical(x);
                const V3 rq = ref.canon(x);
                ASSERT_EQ(V3({cx[0], cx[1], cx[2]}), rq) << s << x;
                ASSERT_EQ(lp.fromCanonical(cx), x);
                ASSERT_EQ(lp.key(x), ref.key(x)) << s << " " << typeName(t) << " " << x;
                ASSERT_EQ(lp.key(x), canon.key(cx)) << s << x;
                ASSERT_EQ(lp.position(x), canon.position(cx)) << s << x;
            }
            // Extremes: key() is valid for every int32 coordinate, INT32_MIN included.
            for (const Coord& x : {Coord(INT32_MIN), Coord(INT32_MAX), Coord(INT32_MIN, INT32_MAX,
                     0), Coord(INT32_MAX, INT32_MIN, INT32_MIN)}) {
                ASSERT_EQ(lp.key(x), ref.key(x)) << s << x;
            }
        }
    }
}

// x and x + k sigma share their line, for both types (both forms vanish on sigma'), and
// position() advances by k a (naive: x' grows by a) or k (2 (a + b + c) + b) (standard).
TEST(LinePartition, TranslationBySigmaKeepsTheLine)
{
    std::mt19937_64 rng(12);
    for (const Coord& s : testDirections()) {
        for (LineType t : kTypes) {
            const LinePartition lp(s, t);
            const I64 a = lp.canonicalDirection()[0], b = lp.canonicalDirection()[1],
                      c = lp.canonicalDirection()[2];
            const I64 step = t == LineType::Naive ? a : 2 * (a + b + c) + b;
            for (int v = 0; v < 50; ++v) {
                const Coord x = randomVoxel(rng, v % 2 == 1);
                for (int k : {-7, -1, 1, 2, 5}) {
                    const Coord y = x + Coord(s[0] * k, s[1] * k, s[2] * k);
                    ASSERT_EQ(lp.key(y), lp.key(x)) << s << x << k;
                    ASSERT_EQ(lp.position(y) - lp.position(x), k * step) << s << x << k;
                }
            }
        }
    }
}

// ---- brute force over boxes -------------------------------------------------------------------

// Groups every voxel of a 12^3 box (at a random offset within +-10^6) by key, then checks each
// group against the reference line clipped to the box (same set: the key function and the
// inequalities define the same partition) and its shape. Clipping is harmless: a line is
// componentwise monotone in canonical coordinates, so its part in a box is one contiguous piece.
// 418 directions x 2 types x 1728 voxels.
TEST(LinePartition, BoxPartitionMatchesDefinitionAndShape)
{
    constexpr int kSide = 12;
    std::mt19937_64 rng(13);
    for (const Coord& s : testDirections()) {
        for (LineType t : kTypes) {
            SCOPED_TRACE(::testing::Message() << "sigma " << s << " " << typeName(t));
            const LinePartition lp(s, t);
            const Reference ref(s, t);
            const Coord lo = randomVoxel(rng, false), hi = lo + Coord(kSide - 1);
            const openvdb::CoordBBox box(lo, hi);

            std::unordered_map<LineKey, std::vector<Coord>> groups;
            for (auto it = box.begin(); it; ++it) groups[lp.key(*it)].push_back(*it);

            // Canonical bounds of the box.
            V3 clo, chi;
            for (int n = 0; n < 3; ++n) {
                const I64 u = ref.sign[ref.perm[n]] * I64(lo[ref.perm[n]]);
                const I64 w = ref.sign[ref.perm[n]] * I64(hi[ref.perm[n]]);
                clo[n] = std::min(u, w);
                chi[n] = std::max(u, w);
            }
            size_t total = 0;
            for (auto& [key, voxels] : groups) {
                total += voxels.size();
                // Same set as the reference line clipped to the box.
                std::set<Coord> expected;
                for (I64 x = clo[0]; x <= chi[0]; ++x) {
                    const auto [ylo, yhi] = ref.yRange(key.i, x);
                    const auto [zlo, zhi] = ref.zRange(key.j, x);
                    for (I64 y = std::max(ylo, clo[1]); y <= std::min(yhi, chi[1]); ++y) {
                        for (I64 z = std::max(zlo, clo[2]); z <= std::min(zhi, chi[2]); ++z) {
                            expected.insert(ref.orig({x, y, z}));
                        }
                    }
                }
                ASSERT_EQ(expected, std::set<Coord>(voxels.begin(), voxels.end()));

                // Walk the group in position order.
                std::sort(voxels.begin(), voxels.end(), [&](const Coord& u, const Coord& v) {
                    return lp.position(u) < lp.position(v);
                });
                int blockSteps = 0;
                for (size_t n = 0; n + 1 < voxels.size(); ++n) {
                    const Coord &u = voxels[n], &v = voxels[n + 1];
                    ASSERT_LT(lp.position(u), lp.position(v)) << u << v;  // injective
                    if (t == LineType::Naive) {
                        // One voxel per major coordinate, contiguous, x' == position; each
                        // step a 26-neighbour moving with sigma's signs.
                        ASSERT_EQ(lp.canonical(v)[0], lp.canonical(u)[0] + 1) << u << v;
                        ASSERT_EQ(lp.position(u), lp.canonical(u)[0]);
                        ASSERT_TRUE(followsSigma(u, v, s)) << u << v;
                    } else if (l1(u, v) == 1) {
                        ASSERT_TRUE(followsSigma(u, v, s)) << u << v;  // a 6-step along sigma
                    } else {
                        // Otherwise the middle of a 2x2 block: canonical (0, +1, -1).
                        const Coord d = lp.canonical(v) - lp.canonical(u);
                        ASSERT_EQ(d, Coord(0, 1, -1)) << u << v;
                        ++blockSteps;
                    }
                }
                if (t == LineType::Standard) {
                    // Blocks need both minor projections to step: impossible if b or c is 0.
                    const Coord& cs = lp.canonicalDirection();
                    if (cs[1] == 0 || cs[2] == 0) {
                        ASSERT_EQ(blockSteps, 0);
                    }
                    // 6-connected as a set: flood fill by face neighbours reaches all.
                    const std::set<Coord> set(voxels.begin(), voxels.end());
                    std::set<Coord> seen{voxels.front()};
                    std::vector<Coord> stack{voxels.front()};
                    while (!stack.empty()) {
                        const Coord u = stack.back();
                        stack.pop_back();
                        for (int k = 0; k < 3; ++k) {
                            for (int d : {-1, 1}) {
                                Coord v = u;
                                v[k] += d;
                                if (set.count(v) && seen.insert(v).second) stack.push_back(v);
                            }
                        }
                    }
                    ASSERT_EQ(seen.size(), set.size());
                }
            }
            ASSERT_EQ(total, size_t(box.volume()));
        }
    }
}

// ---- long walks -------------------------------------------------------------------------------

// Generates a line from the inequalities over at least two periods (2a + 40 major steps) around a
// start voxel (near 0 +- 10^6 and near +-2^30) and checks it voxel by voxel: same key, off-line
// neighbours on other keys, per-slice shape, step rules, and distance to the Euclidean line.
// 418 directions x 2 types x 3 starts; up to ~2000 slices per walk.
TEST(LinePartition, WalksAlongGeneratedLines)
{
    std::mt19937_64 rng(14);
    for (const Coord& s : testDirections()) {
        for (LineType t : kTypes) {
            SCOPED_TRACE(::testing::Message() << "sigma " << s << " " << typeName(t));
            const LinePartition lp(s, t);
            const Reference ref(s, t);
            const I64 a = ref.a, b = ref.b, c = ref.c;
            const bool naive = t == LineType::Naive;
            for (int start = 0; start < 3; ++start) {
                const Coord v0 = randomVoxel(rng, start > 0);
                const LineKey key = lp.key(v0);
                const I64 x0 = ref.canon(v0)[0], half = a + 20;

                std::vector<Coord> line;
                I64 prevYhi = 0, prevZhi = 0, wideY = 0, wideZ = 0;
                for (I64 x = x0 - half; x <= x0 + half; ++x) {
                    const auto [ylo, yhi] = ref.yRange(key.i, x);
                    const auto [zlo, zhi] = ref.zRange(key.j, x);
                    // Slice sizes: 1 for naive (w = a), 1 or 2 for standard (w = a + b <= 2a),
                    // exactly 1 when the minor component is 0 (w = a again).
                    ASSERT_GE(yhi, ylo);
                    ASSERT_GE(zhi, zlo);
                    ASSERT_LE(yhi - ylo, naive || b == 0 ? 0 : 1);
                    ASSERT_LE(zhi - zlo, naive || c == 0 ? 0 : 1);
                    // Slices chain: the top corner of slice x is below the bottom of slice x+1
                    // (naive: y, z grow by 0 or 1) or equal to it (standard: 6-connected).
                    if (x > x0 - half) {
                        if (naive) {
                            ASSERT_TRUE(ylo - prevYhi == 0 || ylo - prevYhi == 1);
                            ASSERT_TRUE(zlo - prevZhi == 0 || zlo - prevZhi == 1);
                        } else {
                            ASSERT_EQ(ylo, prevYhi);
                            ASSERT_EQ(zlo, prevZhi);
                        }
                    }
                    prevYhi = yhi;
                    prevZhi = zhi;
                    // Over the first period, count the slices where each projection steps.
                    if (x < x0 - half + a) {
                        wideY += yhi - ylo;
                        wideZ += zhi - zlo;
                    }
                    for (I64 y = ylo; y <= yhi; ++y) {
                        for (I64 z = zlo; z <= zhi; ++z) {
                            const Coord v = ref.orig({x, y, z});
                            ASSERT_EQ(lp.key(v), key) << v;
                            line.push_back(v);
                        }
                    }
                    // The voxels just off the slice are on other lines.
                    for (I64 z = zlo; z <= zhi; ++z) {
                        ASSERT_NE(lp.key(ref.orig({x, ylo - 1, z})), key);
                        ASSERT_NE(lp.key(ref.orig({x, yhi + 1, z})), key);
                    }
                    for (I64 y = ylo; y <= yhi; ++y) {
                        ASSERT_NE(lp.key(ref.orig({x, y, zlo - 1})), key);
                        ASSERT_NE(lp.key(ref.orig({x, y, zhi + 1})), key);
                    }
                }
                // A standard 2D line of slope b/a steps b times per period of a columns.
                if (!naive) {
                    ASSERT_EQ(wideY, b);
                    ASSERT_EQ(wideZ, c);
                }

                std::sort(line.begin(), line.end(), [&](const Coord& u, const Coord& v) {
                    return lp.position(u) < lp.position(v);
                });
                // The y' and z' deviations from the Euclidean line lie in [0, w / a), so two
                // voxels differ by less than w / a in each: bound on the distance to the line
                // through the first voxel along sigma (naive: sqrt 2; standard: <= 2 sqrt 2).
                const long double bound = std::hypot((long double)ref.wab / a,
                    (long double)ref.wac / a);
                const Coord first = line.front();
                for (size_t n = 0; n < line.size(); ++n) {
                    const Coord& v = line[n];
                    ASSERT_LT(distanceToLine(v, first, s), bound) << v;
                    if (n == 0) continue;
                    const Coord& u = line[n - 1];
                    ASSERT_LT(lp.position(u), lp.position(v)) << u << v;
                    // The position order is the order of sigma . v (projection on the ray),
                    // ties (b == c in a 2x2 block) broken by the lower y' first.
                    const I64 pu = I64(s[0]) * u[0] + I64(s[1]) * u[1] + I64(s[2]) * u[2];
                    const I64 pv = I64(s[0]) * v[0] + I64(s[1]) * v[1] + I64(s[2]) * v[2];
                    ASSERT_TRUE(pu < pv || (pu == pv && ref.canon(u)[1] < ref.canon(v)[1]));
                    if (naive) {
                        ASSERT_TRUE(followsSigma(u, v, s)) << u << v;
                        ASSERT_EQ(lp.position(v), lp.position(u) + 1);
                    } else if (l1(u, v) != 1 || !followsSigma(u, v, s)) {
                        ASSERT_EQ(lp.canonical(v) - lp.canonical(u), Coord(0, 1, -1)) << u << v;
                    }
                }
                // Naive: exactly one voxel per major coordinate.
                if (naive) {
                    ASSERT_EQ(line.size(), size_t(2 * half + 1));
                }
            }
        }
    }
}

// ---- documented caveats -----------------------------------------------------------------------

// The two-cylinder standard line is 6-connected but not always a simple 6-path: sigma (2, 1, 1),
// line (0, 0) holds the 2x2 block x = 0, y, z in {0, 1}: -x + 2y and -x + 2z both lie in [0, 3).
TEST(LinePartition, StandardLineCanHoldA2x2Block)
{
    const LinePartition lp(Coord(2, 1, 1), LineType::Standard);
    for (const Coord& v : {Coord(0, 0, 0), Coord(0, 1, 0), Coord(0, 0, 1), Coord(0, 1, 1)}) {
        EXPECT_EQ(lp.key(v), (LineKey{0, 0})) << v;
    }
    // Positions 2 (x + y + z) + y: 0, 3, 2, 5 - distinct, (0,0,1) before (0,1,0).
    EXPECT_EQ(lp.position(Coord(0, 0, 1)), 2);
    EXPECT_EQ(lp.position(Coord(0, 1, 0)), 3);
    // The naive line through the origin has one voxel at x = 0.
    const LinePartition naive(Coord(2, 1, 1), LineType::Naive);
    EXPECT_NE(naive.key(Coord(0, 1, 0)), naive.key(Coord(0, 0, 0)));
}

// -sigma yields another (equally valid) partition: the half-open bounds fall on the other side,
// so a solver must use one partition per +-sigma pair. sigma (2, 1, 0), naive: -x + 2y is 0 at
// the origin and 1 at (1, 1, 0): both in [0, 2) for sigma, but 0 and -1 for -sigma.
TEST(LinePartition, OppositeDirectionIsAnotherPartition)
{
    const LinePartition plus(Coord(2, 1, 0), LineType::Naive);
    const LinePartition minus(Coord(-2, -1, 0), LineType::Naive);
    EXPECT_EQ(plus.key(Coord(0, 0, 0)), plus.key(Coord(1, 1, 0)));
    EXPECT_NE(minus.key(Coord(0, 0, 0)), minus.key(Coord(1, 1, 0)));
}

// ---- key type ---------------------------------------------------------------------------------

TEST(LinePartition, LineKeyOrderEqualityAndHash)
{
    EXPECT_TRUE((LineKey{1, 2}) == (LineKey{1, 2}));
    EXPECT_TRUE((LineKey{1, 2}) != (LineKey{2, 1}));
    EXPECT_TRUE((LineKey{-1, 5}) < (LineKey{0, -5}));
    EXPECT_TRUE((LineKey{0, -5}) < (LineKey{0, 4}));
    EXPECT_FALSE((LineKey{0, 4}) < (LineKey{0, 4}));
    // Neighbouring keys (the common case: adjacent lines) get distinct hashes: a 64-bit mix of
    // 201^2 keys should have no collision (chance ~ 2^-35 for a random function).
    std::unordered_set<size_t> hashes;
    for (I64 i = -100; i <= 100; ++i) {
        for (I64 j = -100; j <= 100; ++j) hashes.insert(std::hash<LineKey>()(LineKey{i, j}));
    }
    EXPECT_EQ(hashes.size(), size_t(201 * 201));
    EXPECT_EQ(vdbrad::LineKeyHash()(LineKey{3, -4}), std::hash<LineKey>()(LineKey{3, -4}));
}

} // namespace

TEST(LinePartition, CentredPartitionsAreMirrorImagesAndStillLines)
{
    // centreOn(min + max): reflecting a voxel through the centre of a box along any set of axes
    // maps the lines of sigma onto the lines of the reflected direction (as a bijection), and a
    // naive line still holds at most one voxel per major coordinate. Exhaustive over a 13 x 9 x 11
    // box (odd and even extents, so both parities of the centre occur) for random directions.
    std::mt19937 rng(77);
    std::uniform_int_distribution<int> comp(-7, 7);
    const Coord lo(-3, 2, 0), hi(9, 10, 10);
    int tested = 0;
    while (tested < 60) {
        const Coord sigma(comp(rng), comp(rng), comp(rng));
        if (sigma == Coord(0)) continue;
        if (std::gcd(std::gcd(std::abs(sigma.x()), std::abs(sigma.y())), std::abs(sigma.z())) != 1) {
            continue;
        }
        ++tested;
        for (LineType type : {LineType::Naive, LineType::Standard}) {
            for (int flips = 1; flips < 8; ++flips) {
                const Coord mirrored((flips & 1) ? -sigma.x() : sigma.x(),
                    (flips & 2) ? -sigma.y() : sigma.y(), (flips & 4) ? -sigma.z() : sigma.z());
                LinePartition p(sigma, type), q(mirrored, type);
                p.centreOn(lo + hi);
                q.centreOn(lo + hi);
                std::map<std::pair<I64, I64>, std::pair<I64, I64>> forward, backward;
                std::map<std::pair<I64, I64>, std::set<I64>> majors;
                for (int x = lo.x(); x <= hi.x(); ++x) for (int y = lo.y(); y <= hi.y(); ++y) {
                    for (int z = lo.z(); z <= hi.z(); ++z) {
                        const Coord c(x, y, z);
                        const Coord m((flips & 1) ? lo.x() + hi.x() - x : x,
                            (flips & 2) ? lo.y() + hi.y() - y : y,
                            (flips & 4) ? lo.z() + hi.z() - z : z);
                        const LineKey a = p.key(c), b = q.key(m);
                        const auto ka = std::make_pair(a.i, a.j), kb = std::make_pair(b.i, b.j);
                        auto f = forward.emplace(ka, kb).first;
                        ASSERT_EQ(f->second, kb) << sigma << " flips " << flips;
                        auto g = backward.emplace(kb, ka).first;
                        ASSERT_EQ(g->second, ka) << sigma << " flips " << flips;
                        if (type == LineType::Naive) {
                            ASSERT_TRUE(majors[ka].insert(c[p.majorAxis()]).second)
                                << "two voxels of one naive line share a major coordinate, "
                                << sigma;
                        }
                    }
                }
            }
        }
    }
}

TEST(LinePartition, BoxKeysEqualKeysInsideTheirBox)
{
    // The multiplication-only keys must equal key() for every voxel of the box, for both line
    // types, every sign pattern, boxes on either side of the origin and near the int32 limits.
    std::mt19937 rng(31);
    const std::vector<CoordBBox> boxes = {
        CoordBBox(Coord(-40, -33, -17), Coord(41, 30, 52)),
        CoordBBox(Coord(1000, 2000, -3000), Coord(1100, 2050, -2900)),
        CoordBBox(Coord(-2000000, -1000000, 5), Coord(1500000, 3, 2000000)),
        CoordBBox(Coord(-(1 << 30), -(1 << 30), -(1 << 30)), Coord(1 << 30, 1 << 30, 1 << 30))};
    size_t checked = 0, validBoxes = 0, wrong = 0;
    forCentredPartitions(rng, 60, boxes,
        [&](const Coord& sigma, const CoordBBox& box, const LinePartition& p) {
            const LinePartition::BoxKeys keys(p, box);
            if (!keys.valid()) return;
            ++validBoxes;
            for (int s = 0; s < 2000; ++s) {
                const Coord c = boxSample(rng, box, s);
                if (keys.key(c) != p.key(c) && ++wrong < 5) {
                    ADD_FAILURE() << sigma << " " << c;
                }
                ++checked;
            }
        });
    EXPECT_EQ(wrong, 0u);
    EXPECT_GT(validBoxes, 250u);
    EXPECT_GT(checked, 500000u);
    // Where the shifted numerators could pass 2^64 / 2w the box is refused (callers fall back
    // to key()): a huge direction over the whole int32 range.
    LinePartition huge(Coord(1 << 20, (1 << 20) - 1, 3), LineType::Standard);
    huge.centreOn(Coord(0));
    EXPECT_FALSE(LinePartition::BoxKeys(huge,
        CoordBBox(Coord(INT_MIN + 1), Coord(INT_MAX))).valid());
}

TEST(LinePartition, VectorSlotsEqualDenseKeys)
{
    // BoxKeys::slots (32-bit lanes, vectorised) must give (i - i0) * nj + (j - j0) of key() for
    // every voxel, or refuse the box, writing nothing.
    std::mt19937 rng(57);
    const std::vector<CoordBBox> boxes = {
        CoordBBox(Coord(-40, -33, -17), Coord(41, 30, 52)),
        CoordBBox(Coord(0), Coord(0)),
        CoordBBox(Coord(1000, 2000, -3000), Coord(1100, 2050, -2900)),
        CoordBBox(Coord(-1000000000, 7, 999999000), Coord(-999999000, 1000, 1000000000)),
        // min + max overflows int32, so the partition is far from centred: refused or exact.
        CoordBBox(Coord(-2000000000, 7, 1999999000), Coord(-1999999000, 1000, 2000000000)),
        CoordBBox(Coord(-2000000, -1000000, 5), Coord(1500000, 3, 2000000))};
    size_t checked = 0, accepted = 0, refused = 0, wrong = 0, smallRefused = 0;
    forCentredPartitions(rng, 80, boxes,
        [&](const Coord& sigma, const CoordBBox& box, const LinePartition& p) {
            const LinePartition::BoxKeys keys(p, box);
            int64_t i0 = INT64_MAX, i1 = INT64_MIN, j0 = INT64_MAX, j1 = INT64_MIN;
            for (int c = 0; c < 8; ++c) {
                const LineKey k = p.key(corner(box, c));
                i0 = std::min(i0, k.i); i1 = std::max(i1, k.i);
                j0 = std::min(j0, k.j); j1 = std::max(j1, k.j);
            }
            std::vector<Coord> voxels;
            for (int s = 0; s < 1499; ++s) voxels.push_back(boxSample(rng, box, s));
            const int64_t nj = j1 - j0 + 1;
            // An odd count, so that a vector loop's remainder runs too.
            std::vector<uint32_t> slots(voxels.size(), 0xdeadbeefu);
            if (!keys.slots(voxels.data(), slots.size(), i0, j0, nj, slots.data())) {
                ++refused;
                // The small centred boxes (the first four) always fit: refusals there were a
                // bound one index too high (a third of the directions of a 565-voxel Cornell
                // box took the scalar path).
                if (&box - boxes.data() < 4) ++smallRefused;
                for (uint32_t v : slots) wrong += v != 0xdeadbeefu;   // nothing written
                return;
            }
            ++accepted;
            for (size_t k = 0; k < slots.size(); ++k) {
                const LineKey key = p.key(voxels[k]);
                if (int64_t(slots[k]) != (key.i - i0) * nj + (key.j - j0) && ++wrong < 5) {
                    ADD_FAILURE() << sigma << " " << voxels[k] << " " << box;
                }
                ++checked;
            }
        });
    EXPECT_EQ(wrong, 0u);
    // The small centred boxes (the first four, wherever they lie) take the vector path; the
    // boxes millions of voxels wide do not fit 32-bit lanes and are refused.
    EXPECT_GT(accepted, 4u * 100u);
    EXPECT_GT(refused, 100u);
    EXPECT_EQ(smallRefused, 0u);
    EXPECT_GT(checked, 400000u);
}
