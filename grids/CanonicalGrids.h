// Canonical scenes and clouds shared by tests, samples and benchmarks.
//
// Every builder returns the grids of one `.vdb` file following vdbrad's scene contract
// (docs/scene-contract.md): a surface scene is a Vec3f grid `normal` (world-space outward unit
// normals, active exactly on the surface voxels) plus `albedo` (float or Vec3f) and `emission`
// (float) grids on the same transform; a cloud is a fog-volume FloatGrid `density` (extinction per
// world unit). Each builder documents the exact answer the scene has, where one exists, and the
// functions at the end of this file compute those answers so tests and benchmarks need not
// re-derive them.
//
// Resolution `res` is the number of voxels along the scene's longest axis; the voxel size is
// (world extent) / res, so a scene keeps its world size at every resolution.
#pragma once

#include <openvdb/openvdb.h>

#include <functional>
#include <string>
#include <vector>

namespace vdbrad {
namespace grids {

/// Knobs shared by the builders. A negative value means "the builder's documented default".
struct BuildParams
{
    int res = 64;            ///< voxels along the longest axis, in [1, 4096]
    float albedo = -1.f;     ///< surface reflectance or single-scattering albedo, in [0, 1]
    float emission = -1.f;   ///< emitted radiosity of the emitters, >= 0
    float radius = -1.f;     ///< disk: emitter radius (world units)
    float height = -1.f;     ///< disk, plates: distance between emitter and receiver (world units)
    float tau = -1.f;        ///< slab: vertical optical thickness; cumulus: optical diameter;
                             ///< step-cloud: the thick columns' thickness; cornell: the fog's
                             ///< optical depth across the room
    unsigned seed = 1;       ///< cumulus: random seed of the procedural shape
};

/// @brief Closed cube of side 1 (world units), `res` voxels per side. Surface voxels: the one-voxel
/// shell of the cube; normals point inward (edges and corners: normalised sum of the faces').
/// Uniform albedo rho (default 0.5) and emission E (default 1).
/// Exact answer: every voxel's radiosity is E / (1 - rho) (the furnace).
openvdb::GridPtrVec makeFurnaceBox(const BuildParams&);

/// @brief Closed spherical enclosure of diameter 1, R = res/2 voxels. Surface voxels: voxels whose
/// centre lies outside the sphere and that have a 26-neighbour inside it (so the shell blocks every
/// 26-connected line); normals point to the centre. Uniform rho (default 0.5), E (default 1).
/// Exact answer: every voxel's radiosity is E / (1 - rho).
openvdb::GridPtrVec makeFurnaceSphere(const BuildParams&);

/// @brief A disk of radius r (default 0.25) at y = 0 facing +y, emitting E (default 1) with
/// albedo 0, under a 1 x 1 receiver square at height h (default 0.25) facing -y with albedo 1
/// (so its radiosity equals its irradiance) and no emission; both one voxel thick, centred on the
/// vertical axis x = z = 0.5 (world); res voxels across the receiver.
/// Exact answer: receiver radiosity at horizontal distance a from the axis is
/// diskIrradiance(E, r, h, a); on the axis E r^2 / (r^2 + h^2).
openvdb::GridPtrVec makeDisk(const BuildParams&);

/// @brief Two parallel aligned unit squares at distance h (default 0.5), one voxel thick: the lower
/// one (y = 0, facing +y) emits E (default 1) with albedo 0, the upper one (facing -y) has albedo 1
/// and no emission. Exact answer: upper radiosity at a point = E * rectangleFactor(...), its mean
/// over the upper plate = E * parallelSquaresViewFactor(1, h).
openvdb::GridPtrVec makePlates(const BuildParams&);

/// @brief A small square lamp over a floor: a unit floor at y = 0 facing +y (albedo rho, default
/// 0.5, no emission; res x res voxels) and, at height h (default 0.25), a square emitter facing
/// -y (emission E, default 1, albedo 0): the columns whose centres lie within r (default 0.05)
/// of the axis x = z = 0.5 in both x and z (at least the one or two nearest the axis). Nothing else reflects, so the floor's radiosity is
/// exactly rho E F(point -> the emitter's cells): lampFloorRadiosity().
openvdb::GridPtrVec makeLamp(const BuildParams&);

/// @brief The Cornell box (Cornell's measured geometry, in metres; y up, open towards -z): white,
/// red (left, x = 0.556) and green (right, x = 0) walls, the short and tall blocks and the ceiling
/// light (0.213..0.343 x 0.227..0.332), emission E (default 1, grey). RGB albedo grid:
/// white (0.73, 0.73, 0.73), red (0.63, 0.065, 0.05), green (0.14, 0.45, 0.091).
/// Surface voxels: solid voxels with a 26-neighbour in the room's air. With tau > 0 (default 0:
/// none) a fog-volume `density` grid fills the air voxels, extinction tau / 0.556 per metre
/// (optical depth tau across the room's width): the foggy Cornell box.
/// No closed-form answer; used for colour bleeding, speed and the trade study.
openvdb::GridPtrVec makeCornell(const BuildParams&);

/// @brief A homogeneous cloud slab: 1 x ny vs x 1 (x, y, z; y up), res voxels across x and z and
/// ny = max(1, round(res / 4)) voxels high (0.25 when 4 divides res), density tau / (ny vs) per
/// world unit (so the vertical optical thickness is exactly tau, default 10),
/// single-scattering albedo grid uniform omega (default 1). Meant for periodic boundaries.
openvdb::GridPtrVec makeSlab(const BuildParams&);

/// @brief A procedural cumulus: a deterministic (seeded) heap of overlapping spheres with a
/// value-noise eroded, smooth edge, inside a unit cube; density scaled so that the optical path
/// through the centre along the vertical is about tau (default 20).
openvdb::GridPtrVec makeCumulus(const BuildParams&);

/// @brief The step cloud of the Intercomparison of 3D Radiation Codes (I3RC, phase 1), in km:
/// 32 columns of 0.015625 over a period of 0.5 along x, 0.25 high (y up), uniform along z (one
/// voxel deep); the first 16 columns of vertical optical thickness tau / 9, the last 16 of tau
/// (default 18: 2 and 18). res: voxels along x, a multiple of 32; res / 2 layers. Meant for
/// periodic boundaries.
openvdb::GridPtrVec makeStepCloud(const BuildParams&);

/// One named builder: what `vdbrad make NAME` lists.
struct Builder
{
    std::string name;   ///< e.g. "cornell"
    std::string doc;    ///< one line, with the exact answer if any
    std::function<openvdb::GridPtrVec(const BuildParams&)> build;
};

/// All builders, in the order `vdbrad make --help` lists them.
const std::vector<Builder>& builders();

/// The builder called @a name, or nullptr.
const Builder* findBuilder(const std::string& name);

// ---- exact answers -----------------------------------------------------------------------------

/// Irradiance at a point facing a coaxial-parallel uniformly emitting disk (radiosity E, radius r)
/// at distance h, offset a from the axis (Howell's catalogue, configuration B-13):
/// E/2 * (1 - (h^2 + a^2 - r^2) / sqrt((h^2 + a^2 + r^2)^2 - 4 a^2 r^2)).
double diskIrradiance(double E, double r, double h, double a);

/// Point-to-rectangle form factor of a differential area parallel to a rectangle [x0,x1] x [z0,z1]
/// at distance h, the point being at the origin of the rectangle's plane coordinates (corner sum of
/// Howell's configuration B-3).
double rectangleFactor(double x0, double x1, double z0, double z1, double h);

/// Exact radiosity of the lamp scene's floor voxel (i, 0, k): rho E times the B-3 factor from its
/// centre to the cells the emitter's voxels cover.
double lampFloorRadiosity(const BuildParams&, int i, int k);

/// View factor between two parallel, aligned, directly opposed squares of side w at distance h
/// (Howell's configuration C-11).
double parallelSquaresViewFactor(double w, double h);

} // namespace grids
} // namespace vdbrad
