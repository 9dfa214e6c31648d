#include "vdbrad/scene/Sun.h"

#include "vdbrad/core/Constants.h"

#include <algorithm>
#include <cmath>

namespace vdbrad {

openvdb::Vec3d
sunDirection(double zenith, double azimuth, int up, const openvdb::math::Transform& transform)
{
    const int a1 = (up + 1) % 3, a2 = (up + 2) % 3;
    const int first = std::min(a1, a2), second = std::max(a1, a2);
    const double zen = zenith * kPi / 180.0, az = azimuth * kPi / 180.0;
    openvdb::Vec3d toSunWorld(0.0);
    toSunWorld[up] = std::cos(zen);
    toSunWorld[first] = std::sin(zen) * std::cos(az);
    toSunWorld[second] = std::sin(zen) * std::sin(az);
    return transform.baseMap()->applyInverseJacobian(toSunWorld);
}

} // namespace vdbrad
