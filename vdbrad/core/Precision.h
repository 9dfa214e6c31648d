// Precision: the floating-point type of a solver's state, and the rule that picks it.
//
// Storage is float; each accumulator group (SweepSchedule) sums about directions / 8 terms per
// voxel in float (~1e-6 relative), and the groups, the per-voxel normalisation and the residual
// are computed in double. That is enough while 1 / (1 - rho) is moderate, but the fixed point
// amplifies any rounding of B or of the gathered light by 1 / (1 - rho): at rho = 1 - 1e-6 float
// leaves errors of a few percent whatever the iteration count. So a scene with an albedo above
// 0.999 is solved in double throughout (B, the lines' payloads, the accumulators, the hit
// weights, the Anderson history): Precision::Auto; Float and Double force either.
#pragma once

#include "vdbrad/core/Attribute.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace vdbrad {

/// The floating-point type of a solver's state.
enum class Precision
{
    /// Double when some albedo exceeds kDoubleAlbedo, float otherwise.
    Auto,
    Float,
    Double
};

/// Above this albedo, Precision::Auto solves in double: the float floor (~6e-8 of B per sweep,
/// amplified by 1 / (1 - rho) at the fixed point) would exceed ~1e-5.
constexpr float kDoubleAlbedo = 0.999f;

/// "auto", "float" or "double"; throws openvdb::ValueError otherwise.
Precision precisionFromString(const std::string& name);
const char* toString(Precision p);

/// Whether a state with @a albedo (per voxel, grey or RGB) is double under @a precision.
bool solvesInDouble(const Attribute& albedo, Precision precision);

namespace detail {

// The four state types: grey or RGB, float or double (Precision). Scalar is one channel; Acc is
// a group's accumulator, Wide the type the groups are added in.
//
// In float, each group sums about directions / 8 terms per voxel: float keeps those short
// sums to ~1e-6 relative and halves the memory traffic of the sweeps' hottest write; the groups
// are added in double. In double everything is double (the hit weights too), so that a closed
// room's renormalised weights add up to 1 within ~1e-15 and 1 / (1 - rho) = 1e6 leaves 1e-9.
template<typename ValueT> struct Traits;
template<> struct Traits<float> { using Acc = float; using Wide = double; using Scalar = float; };
template<> struct Traits<openvdb::Vec3f>
{
    using Acc = openvdb::Vec3f;
    using Wide = openvdb::Vec3d;
    using Scalar = float;
};
template<> struct Traits<double>
{
    using Acc = double;
    using Wide = double;
    using Scalar = double;
};
template<> struct Traits<openvdb::Vec3d>
{
    using Acc = openvdb::Vec3d;
    using Wide = openvdb::Vec3d;
    using Scalar = double;
};

// Largest channel of a value, and of a difference (computed in the value's own precision).
template<typename T> double magnitude(T v) { return std::abs(double(v)); }
template<typename T> double magnitude(const openvdb::math::Vec3<T>& v)
{
    return double(std::max({v[0], v[1], v[2]}));
}
template<typename T> double magnitudeOfDiff(T a, T b) { return magnitude(a - b); }
template<typename T>
double magnitudeOfDiff(const openvdb::math::Vec3<T>& a, const openvdb::math::Vec3<T>& b)
{
    const openvdb::math::Vec3<T> d = a - b;
    return double(std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])}));
}
// Voxel i's value of an attribute, as a state value.
template<typename ValueT> ValueT value(const Attribute& a, size_t i);
template<> inline float value<float>(const Attribute& a, size_t i) { return a.grey(i); }
template<> inline openvdb::Vec3f value<openvdb::Vec3f>(const Attribute& a, size_t i)
{
    return a.rgb(i);
}
template<> inline double value<double>(const Attribute& a, size_t i) { return a.grey(i); }
template<> inline openvdb::Vec3d value<openvdb::Vec3d>(const Attribute& a, size_t i)
{
    return openvdb::Vec3d(a.rgb(i));
}

} // namespace detail
} // namespace vdbrad
