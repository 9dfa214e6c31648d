// Constants: the numbers every layer shares, defined once.
#pragma once

namespace vdbrad {

/// pi to double precision (M_PI is POSIX, not C++17).
constexpr double kPi = 3.14159265358979323846;

/// The smallest roughness a glossy lobe takes (glossy/Brdf.h): N = 2 / 0.01^2 - 2 ~ 20,000, a
/// near-mirror far sharper than any control-point grid resolves. The scene contract checks a
/// `roughness` grid against it, below the glossy layer.
constexpr double kMinRoughness = 0.1;

} // namespace vdbrad
