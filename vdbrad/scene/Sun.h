// Sun: a distant light, given as users give it: a zenith angle from the up axis, an azimuth, the
// irradiance on a plane normal to its beam and its angular diameter. Clouds take its beam
// (cloud/SolarBeam.h), surface scenes its exact first collision (surface/DirectLight.h).
#pragma once

#include <openvdb/math/Transform.h>

namespace vdbrad {

struct Sun
{
    /// Degrees: zenith from the up axis, in [0, 90); azimuth from the first horizontal axis
    /// towards the second (sunDirection()).
    double zenith = 0.0, azimuth = 0.0;
    /// The up axis: 0 x, 1 y (Houdini), 2 z (Blender).
    int up = 1;
    /// On a plane normal to the beam, per world unit squared, >= 0: linear RGB (grey: equal
    /// channels, and a grey scene stays grey).
    openvdb::Vec3d irradiance{1.0};
    /// The disk's angular diameter, degrees, in [0, 10]: the penumbra's width (ours: 0.53).
    double diameter = 0.53;
};

/// @brief The unit direction towards the sun in @a transform's index space, from its zenith
/// angle (from the @a up axis) and azimuth (from the first horizontal axis towards the second:
/// up y: x then z; up z: x then y; up x: y then z), in degrees. The transform is a uniform
/// scale plus a rotation: world directions map to index ones by the inverse Jacobian.
openvdb::Vec3d sunDirection(double zenith, double azimuth, int up,
    const openvdb::math::Transform& transform);

} // namespace vdbrad
