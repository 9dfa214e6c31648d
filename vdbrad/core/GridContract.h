// GridContract: which grids of a `.vdb` file play which role in vdbrad's scene contract.
//
//   surface   a float grid of class "level set" (vdb_tool -mesh2ls, Houdini, Blender), or
//             a Vec3f grid named `normal` whose active voxels are the surface voxels
//   albedo    float or Vec3f: diffuse reflectance (surfaces) / single-scattering albedo (clouds);
//             where there is none, Houdini's `Cd` or Blender's `color`
//   emission  float or Vec3f: emitted radiosity of surface voxels
//   specular  float or Vec3f, optional: reflectance of a glossy lobe on top of the albedo
//             (MTL Ks; albedo + specular <= 1 per channel)
//   roughness float, optional: the glossy lobe's roughness in (0, 1] (Brdf.h)
//   emission_area  float, optional: the emitting surface's area inside each emitting voxel
//             (world units^2; the voxelizer writes it), so that exact direct light emits the
//             mesh light's power whatever the voxels' coverage
//   density   FloatGrid (fog volume): extinction coefficient per world unit of a cloud
//
// Precision: simulators and Houdini write double grids (Vec3d for vectors) and half-precision
// files; the roles take double and Vec3d grids as single-precision copies, since the solvers
// compute in float (a value beyond float's range is an error, not an infinity), and a float
// grid stored as half arrives as float. GridRoles::notes says what was converted or taken under
// another name; the file's own grids are left as they are, so they pass through to the output
// at their own precision.
//
// Everything else passes through untouched. The full contract is documented in
// docs/scene-contract.md.
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
/// A fog's emission strength where none is named (Blender's and Houdini's fire; Cloud.h).
constexpr const char* kFlame = "flame";
/// Albedo where there is no `albedo` grid: Houdini's colour attribute, then Blender's.
constexpr const char* kHoudiniColour = "Cd";
constexpr const char* kBlenderColour = "color";
constexpr const char* kRadiosity = "radiosity";
/// Int32: the OBJ object or group of each voxel (vdbrad voxelize), passed through by solves.
constexpr const char* kMaterialId = "material_id";
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
    /// What identifyRoles converted (double to float) or took under another name, one line each.
    std::vector<std::string> notes;

    /// The file's grids behind the roles (a converted role's copy is not one of the file's).
    std::vector<openvdb::GridBase::ConstPtr> sources;

    /// Whether @a grid of the file plays a role.
    bool uses(const openvdb::GridBase::ConstPtr& grid) const;
};

/// @brief Find the grids of each role in @a grids, double-precision ones as float copies.
/// @param surfaceName  grid to use as the surface; empty: the vector grid `normal` if present,
///                     otherwise the only level set
/// @param densityName  grid to use as the cloud's density
/// @throw openvdb::TypeError if a reserved or requested grid has the wrong value type
/// @throw openvdb::ValueError if a double grid holds a value beyond float's range
/// @throw openvdb::KeyError  if @a surfaceName names no grid
/// @throw openvdb::ValueError if the surface is ambiguous (several level sets and no name)
/// Missing roles are left null: whether they are required depends on the caller.
GridRoles identifyRoles(const openvdb::GridPtrVec& grids, const std::string& surfaceName = "",
    const std::string& densityName = names::kDensity);

/// @brief @a grid in single precision: a DoubleGrid as a FloatGrid, a Vec3DGrid as a Vec3SGrid
/// (same name, class, metadata and transform; the tree is copied), any other grid as it is.
/// @param note  if not null, set to a line saying what was converted, or that the file stored
///              the grid as half floats; left empty otherwise
/// @throw openvdb::ValueError if a finite value exceeds float's range (naming grid and voxel)
openvdb::GridBase::ConstPtr singlePrecision(const openvdb::GridBase::ConstPtr& grid,
    std::string* note = nullptr);

/// The first grid called @a name, or null.
openvdb::GridBase::ConstPtr findGrid(const openvdb::GridPtrVec& grids, const std::string& name);

/// @brief Check that @a grid's transform suits the sweeps: linear, uniform scale (cubic voxels,
/// rotation allowed), finite positive voxel size.
/// @throw openvdb::ValueError otherwise
void checkTransform(const openvdb::GridBase& grid);

/// @throw openvdb::ValueError unless @a grid is on the same transform as @a reference.
void checkSameTransform(const openvdb::GridBase& grid, const openvdb::GridBase& reference);

} // namespace vdbrad
