// DirectionSet: directions and direction factors from the surfels of a digital sphere
// (Chatelier & Malgouyres, thesis 2006, §4.1.2.2, §4.3.4). See DirectionSet.h for the definitions.
//
// Three facts make the construction small and exact. Let B = B_R, p ∈ B, and call p "exposed"
// when a face neighbour q = p + s·e_m (s = ±1) is outside B.
//
// (1) Every boundary surfel faces away from the origin. |q|² − |p|² = 2·s·p_m + 1 > 0 with
//     integers gives s·p_m ≥ 0. The surfel lies in the plane x_m = p_m + s/2 with outward normal
//     s·e_m, and s·(p_m + s/2) = s·p_m + 1/2 > 0: the origin is strictly on its inner side, so
//     its signed solid angle is > 0 (never 0: the plane is at least 1/2 away). The surfels bound
//     the union of the cubes of B, a closed surface around the origin, so the signed angles add
//     up to 4π; all being positive, every ray from the origin crosses exactly one surfel (up to
//     a null set). No factor can be negative, so no sign handling is needed beyond this proof.
//
// (2) A ray meets at most one exposed voxel. Let σ be primitive, m = ‖σ‖∞ ≥ 1. If kσ is exposed
//     then R² < k²|σ|² + 2km + 1 (the farthest face neighbour gains 2·‖kσ‖∞ + 1); as
//     |σ|² ≥ m² ≥ m and |σ|² ≥ 1, (k+1)²|σ|² ≥ k²|σ|² + 2km + 1 > R², so no larger multiple is
//     in B. Hence each primitive direction collects the surfels of a single voxel, and the number
//     of directions is the number of exposed voxels.
//
// (3) p ∈ B is exposed iff R² < |p|² + 2‖p‖∞ + 1. Fix the axis i of the largest |p_i| and the
//     two other coordinates (a, b): the only exposed candidate is |p_i| = h = ⌊√(R² − a² − b²)⌋
//     (h² ≤ R² − a² − b² < (h+1)²), valid when max(|a|, |b|) ≤ h. So the exposed voxels are
//     enumerated from a disc per axis, O(R²), never touching the interior of the ball.

#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/core/Constants.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <numeric>
#include <string>
#include <utility>

namespace vdbrad {

namespace {


/// ⌊√n⌋ for n ≥ 0, exact: the double estimate is corrected with integer arithmetic.
int64_t
floorSqrt(int64_t n)
{
    int64_t r = static_cast<int64_t>(std::sqrt(static_cast<double>(n)));
    while (r > 0 && r * r > n) --r;
    while ((r + 1) * (r + 1) <= n) ++r;
    return r;
}

/// ⌈√n⌉ for n ≥ 0, exact.
int64_t
ceilSqrt(int64_t n)
{
    const int64_t r = floorSqrt(n);
    return r * r < n ? r + 1 : r;
}

int
gcd3(int a, int b, int c)
{
    return std::gcd(std::gcd(std::abs(a), std::abs(b)), std::abs(c));
}

int64_t
norm2(const openvdb::math::Coord& p)
{
    return int64_t(p.x()) * p.x() + int64_t(p.y()) * p.y() + int64_t(p.z()) * p.z();
}

/// True when the first non-zero component of @a p is positive: the representative of {p, −p}.
bool
isCanonical(const openvdb::math::Coord& p)
{
    for (int i = 0; i < 3; ++i) {
        if (p[i] != 0) return p[i] > 0;
    }
    return false;
}

/// @brief Signed solid angle (sr) of the triangle (a, b, c) seen from the origin, positive when
///        a→b→c turns counter-clockwise around a normal pointing away from the origin.
/// Van Oosterom & Strackee (1983): tan(Ω/2) = det[a b c] / (|a||b||c| + (a·b)|c| + (a·c)|b| +
/// (b·c)|a|). The determinant is formed from the edges, a·((b−a)×(c−a)): for a surfel the edges
/// are exact half-integer vectors and a has half-integer components, so it is exact even far from
/// the origin where det[a b c] would cancel catastrophically; the denominator has no cancellation
/// for the small, distant triangles that dominate, so Ω has a relative error of a few ulps.
double
triangleSolidAngle(const openvdb::math::Vec3d& a, const openvdb::math::Vec3d& b,
    const openvdb::math::Vec3d& c)
{
    const double det = a.dot((b - a).cross(c - a));
    const double la = a.length(), lb = b.length(), lc = c.length();
    const double denom = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    return 2.0 * std::atan2(det, denom);
}

/// @brief Signed solid angle (sr) of the face of the unit cube centred at @a p whose outward
///        normal is s·e_m, positive when the origin is on the cube's side of the face.
double
surfelSolidAngle(const openvdb::math::Coord& p, int m, int s)
{
    // u × v = e_m; for s = −1 swapping u and v makes the corner loop counter-clockwise around
    // the outward normal −e_m.
    openvdb::math::Vec3d u(0.0), v(0.0);
    u[(m + 1) % 3] = 0.5;
    v[(m + 2) % 3] = 0.5;
    if (s < 0) std::swap(u, v);
    openvdb::math::Vec3d centre(p.x(), p.y(), p.z());
    centre[m] += 0.5 * s;
    const openvdb::math::Vec3d c0 = centre - u - v, c1 = centre + u - v, c2 = centre + u + v,
                         c3 = centre - u + v;
    return triangleSolidAngle(c0, c1, c2) + triangleSolidAngle(c0, c2, c3);
}

/// @brief Calls @a op(p) for every exposed voxel p of B_R whose first non-zero component is
///        positive (one per ± pair), by fact (3) of the file comment.
template<typename Op>
void
forEachCanonicalExposedVoxel(int radius, Op op)
{
    const int64_t r2 = int64_t(radius) * radius;
    for (int i = 0; i < 3; ++i) {
        const int j = (i + 1) % 3, l = (i + 2) % 3;
        for (int a = -radius; a <= radius; ++a) {
            const int64_t rest = r2 - int64_t(a) * a;
            const int bMax = static_cast<int>(floorSqrt(rest));
            for (int b = -bMax; b <= bMax; ++b) {
                const int h = static_cast<int>(floorSqrt(rest - int64_t(b) * b));
                // Axis i must hold the largest |component|; on ties the lowest axis owns the
                // voxel, so that each voxel is visited once.
                const int absA = std::abs(a), absB = std::abs(b);
                if ((j < i ? absA >= h : absA > h) || (l < i ? absB >= h : absB > h)) continue;
                for (int s = 1; s >= -1; s -= 2) {
                    openvdb::math::Coord p;
                    p[i] = s * h;
                    p[j] = a;
                    p[l] = b;
                    if (isCanonical(p)) op(p);
                }
            }
        }
    }
}

void
checkRadius(int radius)
{
    if (radius < 1 || radius > DirectionSet::kMaxRadius) {
        OPENVDB_THROW(openvdb::ValueError, "DirectionSet: radius " + std::to_string(radius)
            + " is outside [1, " + std::to_string(DirectionSet::kMaxRadius) + "]");
    }
}

/// @brief Smallest r ≤ @a radius such that the primitive direction @a d is a direction of B_r's
///        boundary: the first multiple kd that is exposed in some B_r. For a given k the
///        smallest such r is ⌈k|d|⌉ (the ball must contain kd) and it works iff
///        ⌈k|d|⌉² < k²|d|² + 2k‖d‖∞ + 1; ⌈k|d|⌉ increases with k, so the first k that works
///        gives the minimum. Returns 0 if none does (cannot happen for a direction of B_radius).
int
appearanceRadiusOf(const openvdb::math::Coord& d, int radius)
{
    const int64_t n2 = norm2(d);
    const int64_t m = std::max({std::abs(d.x()), std::abs(d.y()), std::abs(d.z())});
    for (int64_t k = 1;; ++k) {
        const int64_t r = ceilSqrt(k * k * n2);
        if (r > radius) return 0;
        if (r * r < k * k * n2 + 2 * k * m + 1) return static_cast<int>(r);
    }
}

/// splitmix64 (Steele, Lea & Flood 2014): a tiny generator whose output is fully specified.
uint64_t
splitMix64(uint64_t& state)
{
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/// @brief Number of ± pairs of exposed voxels of B_R, i.e. of directions (fact (2)). Counts the
///        exposed voxels with x ≥ y ≥ z ≥ 0 (one per (y, z) by fact (3)) and weights each by the
///        size of its orbit under the 48 signed axis permutations, which map B_R to itself:
///        O(R²/12) integer work, independent of forEachCanonicalExposedVoxel.
size_t
countPairs(int radius)
{
    const int64_t r2 = int64_t(radius) * radius;
    size_t voxels = 0;
    for (int64_t z = 0; 3 * z * z <= r2; ++z) {
        for (int64_t y = z;; ++y) {
            if (y * y + z * z > r2) break;
            const int64_t x = floorSqrt(r2 - y * y - z * z);
            if (x < y) break; // x only decreases as y grows
            const size_t permutations = (x == y && y == z) ? 1 : (x == y || y == z) ? 3 : 6;
            const size_t signs = size_t(1) << (1 + (y != 0) + (z != 0)); // x ≥ 1 always
            voxels += permutations * signs;
        }
    }
    return voxels / 2;
}

/// Pair counts for R = 0..kMaxRadius (entry 0 unused), computed once (a few milliseconds).
const std::vector<size_t>&
countTable()
{
    static const std::vector<size_t> table = [] {
        std::vector<size_t> counts(DirectionSet::kMaxRadius + 1, 0);
        for (int r = 1; r <= DirectionSet::kMaxRadius; ++r) counts[r] = countPairs(r);
        return counts;
    }();
    return table;
}

} // unnamed namespace


DirectionSet
DirectionSet::fromRadius(int radius)
{
    checkRadius(radius);
    const int64_t r2 = int64_t(radius) * radius;

    struct Entry { openvdb::math::Coord dir; double omega; };
    std::vector<Entry> entries;
    entries.reserve(size_t(7.0 * radius * radius) + 8);

    forEachCanonicalExposedVoxel(radius, [&](const openvdb::math::Coord& p) {
        double omega = 0.0;
        for (int m = 0; m < 3; ++m) {
            for (int s = -1; s <= 1; s += 2) {
                // |p + s·e_m|² = |p|² + 2·s·p_m + 1.
                if (norm2(p) + 2 * int64_t(s) * p[m] + 1 > r2) omega += surfelSolidAngle(p, m, s);
            }
        }
        const int g = gcd3(p.x(), p.y(), p.z());
        entries.push_back({openvdb::math::Coord(p.x() / g, p.y() / g, p.z() / g), omega});
    });

    std::sort(entries.begin(), entries.end(),
        [](const Entry& a, const Entry& b) { return a.dir < b.dir; });

    DirectionSet set;
    set.mRadius = radius;
    const size_t n = entries.size();
    set.mDirections.resize(n);
    set.mUnits.resize(n);
    set.mFactors.resize(n);
    set.mAppearance.resize(n);
    for (size_t k = 0; k < n; ++k) {
        const openvdb::math::Coord& d = entries[k].dir;
        set.mDirections[k] = d;
        set.mUnits[k] = openvdb::math::Vec3d(d.x(), d.y(), d.z()).unit();
        // −p is exposed too, with the mirrored surfels and the same solid angle (B_R is
        // point-symmetric), so the pair holds 2Ω and A = 2Ω / (2π) = Ω / π.
        set.mFactors[k] = entries[k].omega / kPi;
        set.mAppearance[k] = appearanceRadiusOf(d, radius);
    }
    return set;
}


size_t
DirectionSet::countForRadius(int radius)
{
    checkRadius(radius);
    return countTable()[radius];
}


size_t
DirectionSet::maxCount()
{
    return countTable()[kMaxRadius];
}


DirectionSet
DirectionSet::fromCount(int count)
{
    const std::vector<size_t>& counts = countTable();
    if (count < 1 || size_t(count) > counts[kMaxRadius]) {
        OPENVDB_THROW(openvdb::ValueError, "DirectionSet: direction count " + std::to_string(count)
            + " is outside [1, " + std::to_string(counts[kMaxRadius]) + "]");
    }
    // A full scan rather than a bisection: it needs no monotonicity argument.
    int best = 1;
    size_t bestDistance = size_t(-1);
    for (int r = 1; r <= kMaxRadius; ++r) {
        const size_t c = counts[r];
        const size_t distance = c > size_t(count) ? c - size_t(count) : size_t(count) - c;
        if (distance < bestDistance) {
            best = r;
            bestDistance = distance;
        }
    }
    return fromRadius(best);
}


std::vector<size_t>
DirectionSet::progressiveOrder() const
{
    std::vector<size_t> order(size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::sort(order.begin(), order.end(), [this](size_t a, size_t b) {
        if (mAppearance[a] != mAppearance[b]) return mAppearance[a] < mAppearance[b];
        const int64_t na = norm2(mDirections[a]), nb = norm2(mDirections[b]);
        if (na != nb) return na < nb;
        return a < b;
    });
    return order;
}


std::vector<size_t>
DirectionSet::shuffledOrder(uint64_t seed) const
{
    std::vector<size_t> order(size());
    std::iota(order.begin(), order.end(), size_t(0));
    uint64_t state = seed;
    for (size_t i = order.size(); i > 1; --i) {
        // Uniform j in [0, i): reject the low 2^64 mod i values so that every residue is
        // equally likely.
        const uint64_t bound = i;
        const uint64_t threshold = (0 - bound) % bound;
        uint64_t x;
        do { x = splitMix64(state); } while (x < threshold);
        std::swap(order[i - 1], order[size_t(x % bound)]);
    }
    return order;
}


double
DirectionSet::hemisphereSum(const openvdb::math::Vec3d& n) const
{
    double sum = 0.0;
    for (size_t k = 0; k < size(); ++k) sum += std::abs(mUnits[k].dot(n)) * mFactors[k];
    return sum;
}


std::vector<double>
DirectionSet::normalisedWeights(const openvdb::math::Vec3d& n) const
{
    std::vector<double> weights(size());
    double sum = 0.0;
    for (size_t k = 0; k < size(); ++k) {
        weights[k] = std::abs(mUnits[k].dot(n)) * mFactors[k];
        sum += weights[k];
    }
    if (!(sum > 0.0) || !std::isfinite(sum)) {
        OPENVDB_THROW(openvdb::ValueError,
            "DirectionSet: normalisedWeights needs a non-empty set and a finite non-zero normal");
    }
    for (double& w : weights) w /= sum;
    return weights;
}

std::vector<double>
DirectionSet::inverseHemisphereSums(const std::vector<openvdb::math::Vec3s>& normals) const
{
    std::vector<double> inv(normals.size());
    // One pass over the directions per normal; walls of explicit scenes repeat a few normals
    // many times, so each range remembers the last few it computed.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, normals.size()),
        [&](const tbb::blocked_range<size_t>& r) {
            std::array<std::pair<openvdb::math::Vec3s, double>, 8> recent;
            size_t filled = 0, next = 0;
            for (size_t i = r.begin(); i != r.end(); ++i) {
                const openvdb::math::Vec3s& n = normals[i];
                double value = 0.0;
                bool found = false;
                for (size_t k = 0; k < filled && !found; ++k) {
                    if (recent[k].first == n) { value = recent[k].second; found = true; }
                }
                if (!found) {
                    value = 1.0 / hemisphereSum(openvdb::math::Vec3d(n));
                    recent[next] = {n, value};
                    next = (next + 1) % recent.size();
                    filled = std::min(filled + 1, recent.size());
                }
                inv[i] = value;
            }
        });
    return inv;
}

size_t
DirectionSet::cellOf(const openvdb::math::Vec3d& d) const
{
    if (empty() || !std::isfinite(d.x()) || !std::isfinite(d.y()) || !std::isfinite(d.z())
            || d.lengthSqr() == 0.0) {
        OPENVDB_THROW(openvdb::ValueError, "DirectionSet::cellOf needs a non-empty set and a "
            "finite non-zero direction");
    }
    // Walk the voxels the ray crosses (unit cubes centred on integer points) until the next one
    // lies outside B_R: the face between them is the one boundary surfel the ray crosses, and
    // it belongs to the last voxel inside, whose primitive direction owns it.
    const int64_t r2 = int64_t(mRadius) * mRadius;
    openvdb::math::Coord p(0, 0, 0);
    int step[3];
    double tMax[3], tDelta[3];
    for (int m = 0; m < 3; ++m) {
        step[m] = d[m] > 0.0 ? 1 : (d[m] < 0.0 ? -1 : 0);
        tDelta[m] = step[m] != 0 ? 1.0 / std::abs(d[m]) : std::numeric_limits<double>::infinity();
        tMax[m] = 0.5 * tDelta[m];
    }
    for (;;) {
        const int m = tMax[0] <= tMax[1] ? (tMax[0] <= tMax[2] ? 0 : 2)
                                         : (tMax[1] <= tMax[2] ? 1 : 2);
        openvdb::math::Coord next = p;
        next[m] += step[m];
        if (norm2(next) > r2) break;
        p = next;
        tMax[m] += tDelta[m];
    }
    const int g = gcd3(p.x(), p.y(), p.z());
    openvdb::math::Coord s(p.x() / g, p.y() / g, p.z() / g);
    const bool negative = !isCanonical(s);
    if (negative) s = -s;
    const auto it = std::lower_bound(mDirections.begin(), mDirections.end(), s);
    if (it == mDirections.end() || *it != s) {
        // Every voxel with a boundary surfel is exposed, so its direction is in the set.
        OPENVDB_THROW(openvdb::ValueError, "DirectionSet::cellOf: no pair for " << s);
    }
    return 2 * size_t(it - mDirections.begin()) + (negative ? 1 : 0);
}


DirectionSet
DirectionSet::withFactors(std::vector<double> factors) const
{
    double sum = 0.0;
    bool positive = factors.size() == size();
    for (double a : factors) {
        positive = positive && a > 0.0 && std::isfinite(a);
        sum += a;
    }
    if (!positive || !(std::abs(sum - 2.0) <= 1e-9)) {
        OPENVDB_THROW(openvdb::ValueError, "direction factors must be one per pair (" << size()
            << "), each > 0, adding up to 2; got " << factors.size() << " adding up to " << sum);
    }
    DirectionSet set = *this;
    set.mFactors = std::move(factors);
    return set;
}

} // namespace vdbrad
