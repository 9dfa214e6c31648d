// LinePartition: the partition of Z^3 into parallel 3D digital lines of one direction.
//
// The radiosity method of Chatelier & Malgouyres (thesis 2006, §4.3.2-4.3.3; "A low complexity
// discrete radiosity method", Computers & Graphics 30(1), 2006) replaces ray casting by grouping
// the voxels of the scene by line: for a direction sigma, every voxel lies on exactly one digital
// line of direction sigma, and two surface voxels see each other along sigma when they are
// consecutive on their line. This class is that grouping: voxel -> (line key, position on line).
//
// Lines are Figueiredo & Reveillès' arithmetic 3D lines ("A contribution to 3D digital lines",
// DGCI 1995): the intersection of the cylinders over two 2D arithmetic lines that share the major
// axis. For a canonical direction sigma' = (a, b, c) with a >= b >= c >= 0, a > 0, voxel
// (x', y', z') lies on line L(i, j) with
//
//     i = floor((-b x' + a y') / w_ab),    j = floor((-c x' + a z') / w_ac),
//
//     naive lines    (26-connected):  w_ab = w_ac = a            (the max norm of sigma')
//     standard lines (6-connected):   w_ab = a + b, w_ac = a + c  (the 2D standard thicknesses)
//
// i.e. i w_ab <= -b x' + a y' < (i + 1) w_ab, and likewise for j. Both linear forms vanish on
// sigma', so x and x + sigma always share their line.
//
// Any other primitive sigma reduces to that case: the axes are sorted by decreasing |sigma_k|
// (ties: the lower axis index first) and every axis whose sigma component is negative is flipped.
// Both steps are folded into per-axis multipliers at construction, so key() is two int64 dot
// products and two floor divisions with no branch on the direction.
//
// Caveat on standard lines (verified by tests/test_lines.cc): with two cylinders only, a line is
// 6-connected as a set but not always a simple 6-path. At a major coordinate where both the y'
// and the z' projection step, the slice is a 2x2 block {y0, y0+1} x {z0, z0+1} (e.g. sigma =
// (2, 1, 1), line (0, 0), x' = 0). Naive lines are always simple 26-paths (one voxel per x').
//
// LinePartition(-sigma) is in general another partition (its half-open bounds fall on the other
// side); to walk the lines of sigma backwards, keep this partition and decrease position().
#pragma once

#include <openvdb/Exceptions.h>
#include <openvdb/math/Coord.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <sstream>
#include <utility>

namespace vdbrad {

/// @brief floor(n / d) for a positive divisor, also for negative @a n (C++ '/' truncates).
/// @details Valid for every int64 @a n and every @a d >= 1.
inline int64_t
floorDiv(int64_t n, int64_t d)
{
    const int64_t q = n / d;
    // Truncation rounded a negative non-integer quotient up; one step down restores the floor.
    return q - static_cast<int64_t>((n % d) < 0);
}

/// Thickness of the lines: naive (26-connected, w = max) or standard (6-connected, w = sums).
enum class LineType { Naive, Standard };

/// Identifies one line of a LinePartition (meaningful only with the partition that made it).
struct LineKey
{
    int64_t i = 0;
    int64_t j = 0;

    bool operator==(const LineKey& o) const { return i == o.i && j == o.j; }
    bool operator!=(const LineKey& o) const { return !(*this == o); }
    /// Lexicographic (i, then j): the order in which sorted sweeps visit lines.
    bool operator<(const LineKey& o) const { return i < o.i || (i == o.i && j < o.j); }
};

/// Hash for unordered containers. Neighbouring lines have consecutive keys, so the two halves are
/// mixed (a multiply-xorshift finaliser) rather than just combined, to spread them over buckets.
struct LineKeyHash
{
    size_t operator()(const LineKey& k) const
    {
        uint64_t h = static_cast<uint64_t>(k.i) * 0x9E3779B97F4A7C15ull;
        h ^= static_cast<uint64_t>(k.j) + 0x632BE59BD9B4E019ull + (h << 6) + (h >> 2);
        h ^= h >> 31;
        h *= 0xBF58476D1CE4E5B9ull;
        h ^= h >> 29;
        return static_cast<size_t>(h);
    }
};


/// @brief The lines of direction sigma (naive or standard) that partition Z^3.
/// @details Immutable after construction; all queries are const and thread-safe.
class LinePartition
{
public:
    /// Largest |sigma_k| accepted: every dot product in key() and position() then stays within
    /// 2 * 2^20 * 2^31 = 2^52 in magnitude for any int32 coordinate, far from int64 overflow.
    static constexpr int32_t kMaxComponent = 1 << 20;

    /// @brief Precompute the reduction of @a sigma to the canonical octant and the line forms.
    /// @param sigma  the line direction: not zero, gcd(|sigma_x|, |sigma_y|, |sigma_z|) = 1,
    ///               each |sigma_k| <= kMaxComponent.
    /// @param type   naive or standard lines.
    /// @throw openvdb::ValueError if @a sigma is zero, not primitive or has a component too large.
    LinePartition(const openvdb::math::Coord& sigma, LineType type)
        : mDirection(sigma), mType(type)
    {
        int64_t g = 0;
        for (int k = 0; k < 3; ++k) {
            const int64_t v = std::abs(static_cast<int64_t>(sigma[k]));
            if (v > kMaxComponent) {
                std::ostringstream os;
                os << "LinePartition: direction " << sigma << " has a component beyond +/-"
                   << kMaxComponent;
                OPENVDB_THROW(openvdb::ValueError, os.str());
            }
            g = gcd(g, v);
        }
        if (g == 0) OPENVDB_THROW(openvdb::ValueError, "LinePartition: zero direction");
        if (g != 1) {
            // n sigma0 gives the lines of sigma0 (forms and w both scale by n); refusing it gives
            // each direction one spelling, so sigma is the period of its lines.
            std::ostringstream os;
            os << "LinePartition: direction " << sigma << " is not primitive (gcd " << g << ")";
            OPENVDB_THROW(openvdb::ValueError, os.str());
        }

        // Stable sort of the axes by decreasing |sigma_k|: ties keep the lower axis first, so
        // the reduction is a fixed function of sigma (and the identity on canonical sigmas).
        mPerm = {0, 1, 2};
        auto mag = [&](int k) { return std::abs(static_cast<int64_t>(sigma[k])); };
        for (int n = 1; n < 3; ++n) {
            for (int m = n; m > 0 && mag(mPerm[m]) > mag(mPerm[m - 1]); --m) {
                std::swap(mPerm[m], mPerm[m - 1]);
            }
        }
        for (int k = 0; k < 3; ++k) mSign[k] = sigma[k] < 0 ? -1 : 1;

        const int64_t a = mag(mPerm[0]), b = mag(mPerm[1]), c = mag(mPerm[2]);
        mCanonical = openvdb::math::Coord(int32_t(a), int32_t(b), int32_t(c));
        mOmegaAB = type == LineType::Naive ? a : a + b;
        mOmegaAC = type == LineType::Naive ? a : a + c;

        // Canonical coordinate n is sign[perm[n]] * xyz[perm[n]]; scatter each canonical form's
        // coefficients onto the original axes so that evaluating it is one plain dot product.
        const int px = mPerm[0], py = mPerm[1], pz = mPerm[2];
        mFormI = {0, 0, 0};
        mFormJ = {0, 0, 0};
        mFormPos = {0, 0, 0};
        mFormI[px] = -b * mSign[px];
        mFormI[py] = a * mSign[py];
        mFormJ[px] = -c * mSign[px];
        mFormJ[pz] = a * mSign[pz];
        if (type == LineType::Naive) {
            mFormPos[px] = mSign[px];                 // x'
        } else {
            mFormPos[px] = 2 * mSign[px];             // 2 (x' + y' + z') + y'
            mFormPos[py] = 3 * mSign[py];
            mFormPos[pz] = 2 * mSign[pz];
        }
    }

    /// @brief The line through voxel @a xyz. Valid for every int32 coordinate.
    LineKey key(const openvdb::math::Coord& xyz) const
    {
        if (!mCentred) {
            return LineKey{floorDiv(dot(mFormI, xyz), mOmegaAB),
                floorDiv(dot(mFormJ, xyz), mOmegaAC)};
        }
        return LineKey{centredIndex(2 * dot(mFormI, xyz) - mOffsetI, mOmegaAB, mInvAB),
            centredIndex(2 * dot(mFormJ, xyz) - mOffsetJ, mOmegaAC, mInvAC)};
    }

    /// @brief Centre the partition on the point @a twiceCentre / 2 (e.g. min + max of a box), so
    /// that mirroring about that point maps the lines of sigma onto the lines of the mirrored
    /// direction: a mirror-symmetric scene then gets a mirror-symmetric solution.
    /// @details A form F becomes T = 2 F(x) - F(twiceCentre), which negates under the point
    /// reflection. Bounds must be a set the negation keeps: at T = 2w k when T is odd (then no
    /// voxel falls on a bound), else at T = w + 2w k, and a voxel on a bound (T and w both even)
    /// goes to the line on the side away from the centre, so that the rule is its own mirror
    /// image. Every line is still a digital line of the same thickness, only translated, except
    /// that in that last case the central line is one voxel thinner where it meets a bound.
    void centreOn(const openvdb::math::Coord& twiceCentre)
    {
        mCentred = true;
        mOffsetI = dot(mFormI, twiceCentre);
        mOffsetJ = dot(mFormJ, twiceCentre);
        mInvAB = 1.0 / double(2 * mOmegaAB);
        mInvAC = 1.0 / double(2 * mOmegaAC);
    }

    /// @brief A coordinate along the line of @a xyz that strictly increases along +sigma.
    /// @details Comparable only between voxels of the same line. Valid for every int32 coordinate.
    ///
    /// Naive lines: the canonical major coordinate x'. The y' range of a slice x' is
    /// [(i w + b x') / a, (i w + b x') / a + 1), one integer, and likewise z': exactly one voxel
    /// per x', so positions on a line are consecutive integers. position(xyz + sigma) = +a.
    ///
    /// Standard lines: p = 2 (x' + y' + z') + y'. Why it is injective and increasing along +sigma:
    /// the slice x' of line (i, j) is Y x Z, Y = the integers of [L, L + (a + b) / a) with
    /// L = (i w_ab + b x') / a, i.e. 1 or 2 of them (exactly 1 if b = 0), and Z likewise. Since
    /// ceil(L + 1 + b/a) - 1 = ceil(L + b/a), max Y(x') = min Y(x' + 1) (and the same for Z), so
    /// every voxel of a later slice is componentwise >= every voxel of an earlier one: the step
    /// count s = x' + y' + z' grows by >= 1 and y' does not decrease, hence p grows by >= 2.
    /// Within a slice, comparable voxels have larger s and y' >= (p grows), and the only
    /// incomparable pair, (y0, z0 + 1) and (y0 + 1, z0) of a 2x2 block, has equal s and y' one
    /// apart, so p differs by 1; it orders them as sigma . xyz does (b >= c), breaking the b = c
    /// tie towards the lower y'. position(xyz + sigma) = position(xyz) + 2 (a + b + c) + b.
    int64_t position(const openvdb::math::Coord& xyz) const { return dot(mFormPos, xyz); }

    /// @brief The canonical coordinates (x', y', z') of @a xyz: permuted by permutation() and
    /// flipped by signs(). Valid for coordinates > INT32_MIN (a flip must not overflow).
    openvdb::math::Coord canonical(const openvdb::math::Coord& xyz) const
    {
        openvdb::math::Coord c;
        for (int n = 0; n < 3; ++n) c[n] = mSign[mPerm[n]] * xyz[mPerm[n]];
        return c;
    }

    /// @brief Inverse of canonical(). Valid for coordinates > INT32_MIN.
    openvdb::math::Coord fromCanonical(const openvdb::math::Coord& c) const
    {
        openvdb::math::Coord xyz;
        for (int n = 0; n < 3; ++n) xyz[mPerm[n]] = mSign[mPerm[n]] * c[n];
        return xyz;
    }

    /// The direction sigma as given.
    const openvdb::math::Coord& direction() const { return mDirection; }
    /// canonical(direction()) = (a, b, c), a >= b >= c >= 0.
    const openvdb::math::Coord& canonicalDirection() const { return mCanonical; }
    LineType type() const { return mType; }
    /// The axis of largest |sigma_k| (the lowest such axis on ties): canonical x'.
    int majorAxis() const { return mPerm[0]; }
    /// permutation()[n] is the original axis that becomes canonical axis n.
    const std::array<int, 3>& permutation() const { return mPerm; }
    /// signs()[k] (k an original axis) is -1 if sigma_k < 0, else +1.
    const std::array<int, 3>& signs() const { return mSign; }
    /// Divisor of the i form: a (naive) or a + b (standard).
    int64_t omegaAB() const { return mOmegaAB; }
    /// Divisor of the j form: a (naive) or a + c (standard).
    int64_t omegaAC() const { return mOmegaAC; }

    /// @brief key() of a centred partition for the voxels of one box, with no division: what the
    /// sweeps call once per voxel and direction.
    /// @details A floor division by the constant 2w becomes the high half of a 64x64-bit product
    /// with M = floor(2^64 / 2w) + 1 on a numerator shifted to be >= 0: for 0 <= n < 2^64 / 2w,
    /// n M / 2^64 exceeds n / 2w by less than 1 / 2w, never enough to reach the next integer.
    /// The box's corners bound the form values; valid() is false when the shifted numerators
    /// could leave that range (coordinates near the int32 limits), and callers then use key().
    class BoxKeys
    {
    public:
        /// @throw openvdb::ValueError if @a partition is not centred (centreOn())
        BoxKeys(const LinePartition& partition, const openvdb::math::CoordBBox& box)
            : mBox(box)
        {
            if (!partition.mCentred) {
                OPENVDB_THROW(openvdb::ValueError, "BoxKeys needs a centred LinePartition");
            }
            mValid = init(mI, partition.mFormI, partition.mOffsetI, partition.mOmegaAB, box)
                && init(mJ, partition.mFormJ, partition.mOffsetJ, partition.mOmegaAC, box);
        }

        bool valid() const { return mValid; }

        /// Equal to LinePartition::key(@a xyz) for @a xyz inside the box, when valid().
        LineKey key(const openvdb::math::Coord& xyz) const
        {
            return LineKey{index(mI, xyz), index(mJ, xyz)};
        }

        /// @brief The dense slots (key.i - i0) * nj + (key.j - j0) of @a n voxels of the box,
        /// written to @a out (what a sweep needs per voxel and direction), in 32-bit vector
        /// arithmetic: several voxels per instruction where the CPU has AVX2 or AVX-512.
        /// @param i0, j0  the smallest keys over the box (those of its corners)
        /// @return false, writing nothing, where the box's form values or the slots do not fit
        /// that arithmetic (boxes millions of voxels wide, or far wider than tall); then use
        /// key().
        bool slots(const openvdb::math::Coord* xyz, size_t n, int64_t i0, int64_t j0, int64_t nj,
            uint32_t* out) const;

    private:
        struct Form
        {
            std::array<int64_t, 3> twiceForm{};   // 2 F
            int64_t offset = 0;                   // F(twiceCentre)
            int64_t omega = 1;
            int64_t shift = 0;                    // a multiple of 2w making numerators >= 0
            int64_t shiftQuotient = 0;            // shift / 2w
            uint64_t magic = 0;                   // floor(2^64 / 2w) + 1
        };

        static bool init(Form& f, const std::array<int64_t, 3>& form, int64_t offset,
            int64_t omega, const openvdb::math::CoordBBox& box)
        {
            for (int k = 0; k < 3; ++k) f.twiceForm[size_t(k)] = 2 * form[size_t(k)];
            f.offset = offset;
            f.omega = omega;
            const int64_t d = 2 * omega;
            int64_t lo = 0, hi = 0;
            for (int c = 0; c < 8; ++c) {
                const openvdb::math::Coord corner(c & 1 ? box.max().x() : box.min().x(),
                    c & 2 ? box.max().y() : box.min().y(), c & 4 ? box.max().z() : box.min().z());
                const int64_t t = 2 * dot(form, corner) - offset;
                lo = c == 0 ? t : std::min(lo, t);
                hi = c == 0 ? t : std::max(hi, t);
            }
            // Numerators lie in [t - 1, t + w] (see centredIndex).
            f.shiftQuotient = lo - 1 < 0 ? (1 - lo + d - 1) / d : 0;
            f.shift = f.shiftQuotient * d;
            f.magic = ~uint64_t(0) / uint64_t(d) + 1;
            const int64_t top = hi + omega + f.shift;   // < 2^53 (kMaxComponent)
            return uint64_t(top) < (~uint64_t(0)) / uint64_t(d);
        }

        static int64_t index(const Form& f, const openvdb::math::Coord& xyz)
        {
            const int64_t t = f.twiceForm[0] * xyz[0] + f.twiceForm[1] * xyz[1]
                + f.twiceForm[2] * xyz[2] - f.offset;
            // centredIndex()'s numerator: odd t as is, even t moved half a period, away from 0.
            const int64_t n = t + ((t & 1) ? 0 : f.omega - int64_t(t < 0)) + f.shift;
            __extension__ using Wide = unsigned __int128;
            const uint64_t q = uint64_t((Wide(uint64_t(n)) * f.magic) >> 64);
            return int64_t(q) - f.shiftQuotient;
        }

        Form mI, mJ;
        openvdb::math::CoordBBox mBox;
        bool mValid = false;
    };

private:
    static int64_t dot(const std::array<int64_t, 3>& f, const openvdb::math::Coord& xyz)
    {
        return f[0] * xyz[0] + f[1] * xyz[1] + f[2] * xyz[2];
    }

    // Line index of the centred, doubled form value T (see centreOn()).
    // Runs once per voxel per direction in the sweeps: the division is a multiplication by the
    // reciprocal, exact after one correction step since |t| < 2^53 (see kMaxComponent).
    static int64_t centredIndex(int64_t t, int64_t omega, double inverse)
    {
        // Odd t: bounds at 2w Z. Even t: bounds at w + 2w Z, ties away from the centre
        // (-floor((w - t) / 2w) = floor((t + w - 1) / 2w) for t < 0).
        const int64_t n = (t & 1) ? t : t + omega - (t < 0 ? 1 : 0);
        const int64_t d = 2 * omega;
        // Truncation is off by at most one, like rounding: the corrections below fix both.
        int64_t q = int64_t(double(n) * inverse);
        const int64_t r = n - q * d;
        q -= int64_t(r < 0);
        q += int64_t(r >= d);
        return q;
    }

    static int64_t gcd(int64_t u, int64_t v)
    {
        while (v != 0) {
            const int64_t r = u % v;
            u = v;
            v = r;
        }
        return u;
    }

    openvdb::math::Coord mDirection;
    openvdb::math::Coord mCanonical;
    LineType mType;
    std::array<int, 3> mPerm;
    std::array<int, 3> mSign;
    int64_t mOmegaAB = 1;
    int64_t mOmegaAC = 1;
    bool mCentred = false;
    int64_t mOffsetI = 0, mOffsetJ = 0;   // centreOn(): F(twiceCentre)
    double mInvAB = 0.0, mInvAC = 0.0;    // centreOn(): 1 / (2 w)
    std::array<int64_t, 3> mFormI;    // i = floor(mFormI . xyz / mOmegaAB)
    std::array<int64_t, 3> mFormJ;    // j = floor(mFormJ . xyz / mOmegaAC)
    std::array<int64_t, 3> mFormPos;  // position = mFormPos . xyz
};

} // namespace vdbrad

namespace std {
template<>
struct hash<vdbrad::LineKey>
{
    size_t operator()(const vdbrad::LineKey& k) const { return vdbrad::LineKeyHash()(k); }
};
} // namespace std
