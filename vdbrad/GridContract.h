// GridContract: which grids of a `.vdb` file play which role in vdbrad's scene contract.
//
//   surface   a FloatGrid of class "level set" (vdb_tool -mesh2ls, Houdini, Blender), or
//             a Vec3f grid named `normal` whose active voxels are the surface voxels
//   albedo    float or Vec3f: diffuse reflectance (surfaces) / single-scattering albedo (clouds)
//   emission  float or Vec3f: emitted radiosity of surface voxels
//   specular  float or Vec3f, optional: reflectance of a glossy lobe on top of the albedo
//             (MTL Ks; albedo + specular <= 1 per channel)
//   roughness float, optional: the glossy lobe's roughness in (0, 1] (Brdf.h)
//   emission_area  float, optional: the emitting surface's area inside each emitting voxel
//             (world units^2; the voxelizer writes it), so that exact direct light emits the
//             mesh light's power whatever the voxels' coverage
//   density   FloatGrid (fog volume): extinction coefficient per world unit of a cloud
//
// Everything else passes through untouched. The full contract is documented in README.md.
#pragma once

#include <openvdb/openvdb.h>

#include <string>
#include <vector>

namespace vdbrad {

/// Grid names the contract reserves.
namespace names {
constexpr const char* kNormal = "normal";
constexpr const char* kAlbedo = "albedo";
constexpr const char* kEmission = "emission";
constexpr const char* kEmissionArea = "emission_area";
constexpr const char* kSpecular = "specular";
constexpr const char* kRoughness = "roughness";
constexpr const char* kDensity = "density";
constexpr const char* kRadiosity = "radiosity";
constexpr const char* kSpecularRadiosity = "specular_radiosity";
} // namespace names

struct GridRoles
{
    enum class SurfaceKind { None, LevelSet, NormalGrid };
    SurfaceKind surfaceKind = SurfaceKind::None;
    openvdb::GridBase::ConstPtr surface;   ///< level set or `normal` grid
    openvdb::GridBase::ConstPtr albedo;
    openvdb::GridBase::ConstPtr emission;
    openvdb::GridBase::ConstPtr emissionArea;
    openvdb::GridBase::ConstPtr specular;
    openvdb::GridBase::ConstPtr roughness;
    openvdb::GridBase::ConstPtr density;
};

/// @brief Find the grids of each role in @a grids.
/// @param surfaceName  grid to use as the surface; empty: the Vec3f grid `normal` if present,
///                     otherwise the only level set
/// @param densityName  grid to use as the cloud's density
/// @throw openvdb::TypeError if a reserved or requested grid has the wrong value type
/// @throw openvdb::KeyError  if @a surfaceName names no grid
/// @throw openvdb::ValueError if the surface is ambiguous (several level sets and no name)
/// Missing roles are left null: whether they are required depends on the caller.
GridRoles identifyRoles(const openvdb::GridPtrVec& grids, const std::string& surfaceName = "",
    const std::string& densityName = names::kDensity);

/// The first grid called @a name, or null.
openvdb::GridBase::ConstPtr findGrid(const openvdb::GridPtrVec& grids, const std::string& name);

/// @brief Check that @a grid's transform suits the sweeps: linear, uniform scale (cubic voxels,
/// rotation allowed), finite positive voxel size.
/// @throw openvdb::ValueError otherwise
void checkTransform(const openvdb::GridBase& grid);

/// @throw openvdb::ValueError unless @a grid is on the same transform as @a reference.
void checkSameTransform(const openvdb::GridBase& grid, const openvdb::GridBase& reference);

} // namespace vdbrad
