// Sky: the light arriving from outside the scene, by direction: a uniform sky, the clear sky of
// Preetham, Shirley & Smits (1999) above a uniform ground, or a latitude-longitude HDR map (an
// environment). The surface solver lets a voxel that faces the outside receive it along each
// sweep direction whose line leaves the scene from it (surface/RadiositySolver.h).
//
// Each direction of the discrete sphere takes the sky's mean radiance over its own cell
// (DirectionSet::cellOf: the surfels the direction owns, which tile the sphere), not one sample,
// so a feature smaller than a cell is neither lost nor counted twice: cellMeans() integrates the
// sky exactly once whatever the direction count.
//
// A map's brightest compact region (a sun a few pixels wide) would still fall in one cell and
// light every voxel facing it through that cell's whole solid angle, without shadows: fromMap()
// splits it off as a Sun (scene/Sun.h), which the solver computes exactly (shadow rays, a
// penumbra), and keeps the rest of the map as the sky.
//
// Directions are world directions (unit, from a receiver towards the sky). The up axis and
// azimuths follow Sun.h: azimuth from the first horizontal axis towards the second (up y: x then
// z; up z: x then y; up x: y then z).
#pragma once

#include "vdbrad/scene/Sun.h"
#include "vdbrad/sweep/DirectionSet.h"

#include <openvdb/math/Transform.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace vdbrad {

/// How Sky::fromMap() splits a sun off a map.
struct SunSplit
{
    /// Split a region off only if its peak radiance is at least this many times the map's
    /// median luminance (an HDRI's sun: 10^3 - 10^5; a bright window or lamp: below).
    double contrast = 100.0;
    /// ... and its angular diameter (of a disk of its solid angle) is at most this, degrees,
    /// or it is at most 4 pixels (a coarse map's sun). The sun's diameter: that of the region,
    /// at most 10 degrees.
    double maxDiameter = 5.0;
    bool enabled = true;
};

class Sky
{
public:
    enum class Kind { None, Uniform, Clear, Map };

    /// No sky (black outside the scene).
    Sky() = default;

    /// @brief The same radiance (linear RGB; grey: equal channels) from every direction.
    /// @throw openvdb::ValueError if a channel is negative or not finite
    static Sky uniform(const openvdb::Vec3d& radiance);

    /// @brief Preetham's clear sky (the paper's luminance in kcd/m^2 as radiance, linear Rec. 709
    /// RGB; Blender's "Preetham" Sky Texture is the same times 0.06, its own scale) for the sun at
    /// @a zenith and @a azimuth degrees about @a up, with atmospheric @a turbidity. Below the
    /// horizon, a uniform ground of radiance groundAlbedo x E / pi, E the horizontal irradiance of
    /// the sky plus @a sunIrradiance x cos(zenith) (the sun's own light, if a sun is given).
    /// @throw openvdb::ValueError if zenith is outside [0, 90), turbidity outside [1, 10],
    ///        the albedo outside [0, 1] or a value is not finite
    static Sky clear(double zenith, double azimuth, int up, double turbidity,
        double groundAlbedo, const openvdb::Vec3d& sunIrradiance = openvdb::Vec3d(0.0));

    /// @brief A latitude-longitude (equirectangular) map: @a width x @a height linear RGB pixels,
    /// top row first. Row v spans polar angles (from @a up) pi v / H to pi (v + 1) / H; column
    /// u's centre looks at azimuth 2 pi (0.5 - (u + 0.5) / W) + rotation (Blender's Environment
    /// Texture with up z). @a rotation, degrees, turns the map about up.
    /// @throw openvdb::ValueError if the size is not positive and consistent, or a pixel is
    ///        negative or not finite
    static Sky fromMap(int width, int height, const std::vector<openvdb::Vec3f>& pixels, int up,
        double rotation = 0.0, const SunSplit& split = SunSplit());

    Kind kind() const;
    bool empty() const { return kind() == Kind::None; }
    /// True if some direction's channels differ: the solution must then be RGB.
    bool isRgb() const;

    /// Radiance arriving from the world direction @a toward (need not be unit).
    openvdb::Vec3d radiance(const openvdb::Vec3d& toward) const;

    /// @brief The mean radiance over each cell of @a directions (index space of @a transform,
    /// whose linear part is a uniform scale and a rotation): [2k] for +direction(k), [2k + 1]
    /// for -direction(k). Uniform skies: exact. Others: sampled on a latitude-longitude raster
    /// of at least ~32 samples per cell (a map: its own pixels, summed in blocks when it has
    /// more), each sample weighted by its solid angle; a cell no sample falls in takes the
    /// radiance at its direction.
    std::vector<openvdb::Vec3f> cellMeans(const DirectionSet& directions,
        const openvdb::math::Transform& transform) const;

    /// A map's split-off sun, if one was found (its irradiance on a plane normal to it).
    const std::optional<Sun>& sun() const;

    /// Irradiance on a horizontal plane facing up from the whole upper hemisphere (numerical).
    openvdb::Vec3d horizontalIrradiance() const;

    /// FNV-1a hash of what defines the sky, continuing from @a seed (a checkpoint fingerprint).
    uint64_t hash(uint64_t seed) const;
    /// One line for logs: "a uniform sky of radiance 0.3", "a clear sky (turbidity 3) ...".
    std::string describe() const;

private:
    struct Data;
    std::shared_ptr<const Data> mData;   // shared: options holding a sky copy cheaply
};

} // namespace vdbrad
