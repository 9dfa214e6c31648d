// RealHarmonics: the real spherical harmonics Y_lm, the basis in which a cloud's phase function
// and moments (cloud/) and glossy lobes (glossy/SphericalHarmonics.h) are expanded over the
// sweeps' directions; below both, so that neither includes the other.
#pragma once

#include <openvdb/Types.h>

namespace vdbrad {

/// @brief Real orthonormal spherical harmonics Y_lm(@a dir), l = 0..order, m = -l..l, written to
/// @a out in the order l^2 + l + m ((order + 1)^2 values). @a dir need not be unit.
void realSphericalHarmonics(int order, const openvdb::Vec3d& dir, double* out);

} // namespace vdbrad
