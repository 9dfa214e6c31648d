// SampleHash: counter-based random numbers. Every estimator draws its samples from a hash of
// (seed, voxel, sample), never from shared generator state, so results do not depend on the
// thread count or the order voxels are visited in.
#pragma once

#include <cstdint>

namespace vdbrad {

/// splitmix64's finaliser: a bijective 64-bit mix.
inline uint64_t
mixHash(uint64_t z)
{
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/// A hash as a double in [0, 1) (its top 53 bits).
inline double unitHash(uint64_t h) { return double(h >> 11) * 0x1.0p-53; }

} // namespace vdbrad
