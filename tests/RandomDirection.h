// Uniformly distributed unit vectors for the tests of functions on the sphere.
#pragma once

#include <openvdb/math/Vec3.h>

#include <random>

namespace vdbrad {
namespace test {

/// A direction uniform on the sphere: a normalised Gaussian vector (isotropic).
inline openvdb::math::Vec3d
randomDirection(std::mt19937_64& rng)
{
    std::normal_distribution<double> g;
    openvdb::math::Vec3d v;
    do { v = openvdb::math::Vec3d(g(rng), g(rng), g(rng)); } while (v.length() < 1e-3);
    return v / v.length();
}

} // namespace test
} // namespace vdbrad
