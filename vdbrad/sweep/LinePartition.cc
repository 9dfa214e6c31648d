#include "vdbrad/sweep/LinePartition.h"

#include "vdbrad/sweep/VectorClones.h"

#include <algorithm>
#include <limits>

namespace vdbrad {

namespace {

// One form of BoxKeys in 32-bit arithmetic, on coordinates relative to the box's minimum.
struct Form32
{
    int32_t a = 0, b = 0, c = 0;
    int32_t base = 0;    // F(min) - offset + shift: the form value plus the shift
    int32_t shift = 0;   // s < shift <=> the centred value t < 0
    int32_t bump = 0;    // w if t is even (the same parity for every voxel: 2F(x) is even)
    int32_t even = 0;    // 1 if t is even, else 0
    uint32_t magic = 0;  // floor(2^32 / 2w) + 1
    uint32_t minus = 0;  // shiftQuotient + the caller's first index, mod 2^32
};

inline uint32_t
index32(const Form32& f, int32_t x, int32_t y, int32_t z)
{
    const int32_t s = f.a * x + f.b * y + f.c * z + f.base;
    const int32_t n = s + f.bump - (f.even & int32_t(s < f.shift));
    return uint32_t((uint64_t(uint32_t(n)) * f.magic) >> 32) - f.minus;
}

// Branch-free and in 32-bit lanes, so that the compiler vectorises it.
VDBRAD_VECTOR_CLONES void
denseSlots(const openvdb::math::Coord* xyz, size_t n, openvdb::math::Coord origin, Form32 fi,
    Form32 fj, uint32_t nj, uint32_t* out)
{
    for (size_t k = 0; k < n; ++k) {
        const int32_t x = xyz[k][0] - origin[0], y = xyz[k][1] - origin[1],
            z = xyz[k][2] - origin[2];
        out[k] = index32(fi, x, y, z) * nj + index32(fj, x, y, z);
    }
}

} // namespace

bool
LinePartition::BoxKeys::slots(const openvdb::math::Coord* xyz, size_t n, int64_t i0, int64_t j0,
    int64_t nj, uint32_t* out) const
{
    if (!mValid || nj <= 0 || nj > int64_t(UINT32_MAX)) return false;
    const openvdb::math::Coord& lo = mBox.min();
    const openvdb::math::Coord ext = mBox.max() - mBox.min();
    constexpr int64_t kLimit = int64_t(1) << 31;
    // Every partial sum of index32 stays within +-bound, and the numerator within [0, top].
    // last: the largest index - first over the box, so that the caller's slots can be checked.
    auto narrow = [&](const Form& f, int64_t first, Form32& g) {
        int64_t bound = 0, top = 0;
        int64_t base = -f.offset + f.shift;
        for (int k = 0; k < 3; ++k) {
            const int64_t t = f.twiceForm[size_t(k)];
            if (std::abs(t) >= kLimit || ext[k] < 0) return false;
            bound += std::abs(t) * int64_t(ext[k]);
            top += std::max<int64_t>(0, t * int64_t(ext[k]));
            base += t * int64_t(lo[k]);
        }
        bound += std::abs(base) + f.omega;
        top += base + f.omega;
        const int64_t d = 2 * f.omega;
        if (bound >= kLimit || top >= kLimit || top >= (int64_t(1) << 32) / d
            || std::abs(f.shift) >= kLimit) {
            return false;
        }
        g.a = int32_t(f.twiceForm[0]);
        g.b = int32_t(f.twiceForm[1]);
        g.c = int32_t(f.twiceForm[2]);
        g.base = int32_t(base);
        g.shift = int32_t(f.shift);
        g.even = (f.offset & 1) ? 0 : 1;
        g.bump = g.even ? int32_t(f.omega) : 0;
        g.magic = uint32_t((uint64_t(1) << 32) / uint64_t(d) + 1);
        g.minus = uint32_t(uint64_t(f.shiftQuotient + first));
        return true;
    };
    Form32 fi, fj;
    if (!narrow(mI, i0, fi) || !narrow(mJ, j0, fj)) return false;
    // Every slot must fit 32 bits (a box much wider than its voxels are many is refused). The
    // keys are monotone in the forms, so the box's extreme keys are at its corners: exact,
    // where a bound from the numerators was one too high for a third of the directions.
    int64_t iLast = std::numeric_limits<int64_t>::min(), jLast = iLast;
    for (int c = 0; c < 8; ++c) {
        const openvdb::math::Coord corner(c & 1 ? mBox.max().x() : lo.x(),
            c & 2 ? mBox.max().y() : lo.y(), c & 4 ? mBox.max().z() : lo.z());
        iLast = std::max(iLast, index(mI, corner) - i0);
        jLast = std::max(jLast, index(mJ, corner) - j0);
    }
    if (iLast < 0 || jLast < 0 || jLast >= nj || (iLast + 1) * nj > int64_t(UINT32_MAX)) {
        return false;
    }
    denseSlots(xyz, n, lo, fi, fj, uint32_t(nj), out);
    return true;
}

} // namespace vdbrad
