// Voxelizer: a triangle mesh -> the surface voxels of a scene (`normal`, `albedo`, `emission`,
// `material_id`).
//
// Topology control (thesis ch. 3): the voxel set of a surface must stop the digital lines the
// solver exchanges light along, or light leaks through walls. In index space (voxel centres at
// integer points, voxel c the cube [c - 1/2, c + 1/2]):
//
//   26-separating: c is a surface voxel iff its closed cube meets a triangle (the "supercover").
//     Two 26-neighbours' centres are joined by a segment inside the union of their two cubes, so
//     a 26-connected path that crosses the surface meets a surface voxel: naive (26-connected)
//     lines, and a fortiori standard ones, are blocked. Over a plane with normal n this is the
//     arithmetic plane of thickness ||n||_1 (Andres' standard plane, closed).
//   6 (for standard lines): c is a surface voxel iff one of its 9 "star" segments c + s d,
//     |s| <= 1/2, meets a triangle, d the 3 axis steps and the 6 face diagonals (e_i +- e_j).
//     A 6-connected path crosses the surface on the half-segment of one of its two voxels, so
//     the shell is 6-separating. The face diagonals are there because vdbrad's standard lines
//     (Figueiredo-Reveilles, see LinePartition.h) are 6-connected sets whose order steps
//     diagonally across their 2x2 blocks: with axis steps only (a plain 6-separating shell,
//     thickness ||n||_inf over a plane) thousands of such steps pass between its voxels
//     (tests/test_voxelizer.cc). Over a plane the star shell is ||n||_1 - min_k |n_k| thick,
//     between the naive plane and the 26-separating standard plane.
//
// Each surface voxel takes its normal (the triangle's winding: counter-clockwise seen from
// outside) and material from the triangle closest to its centre, so the faces of a cube keep
// axis-aligned normals up to its edges. Emission takes precedence: a voxel holding part of a
// light emits, whatever lies closer to its centre, with the mean emission of the light area in
// it (`emission_area`: that area) and the normal and material of the light holding most of it,
// so a light quad just below a ceiling stays a light at every resolution and the voxels emit
// the mesh's power. Lights take the supercover (26) voxels under either separation.
// Candidates are enumerated per triangle along its dominant normal axis: for each voxel column
// of its projected bounding box only the 1-3 voxels within the plane's thickness are tested,
// so the cost is proportional to the triangle's area in voxels, not its bounding-box volume.
#pragma once

#include "vdbrad/mesh/Mesh.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <string>
#include <vector>

namespace vdbrad {

struct VoxelizeOptions
{
    /// Voxel edge in world units (> 0); 0: from @c resolution.
    double voxelSize = 0.0;
    /// Voxels along the longest axis of the mesh's bounding box, used when voxelSize is 0.
    int resolution = 128;
    /// 26 (blocks naive and standard lines; the solver's default naive lines need it) or 6
    /// (thinner; blocks standard lines only; see the file comment).
    int separation = 26;
    /// Albedo of triangles without a material when the mesh has materials (MTL); a mesh with
    /// none gets no `albedo` grid, and the solver's --albedo applies.
    float defaultAlbedo = 0.5f;
    /// Write `specular` and `roughness` grids for materials with MTL `Ks` (glossy lobes); false:
    /// every surface is diffuse.
    bool specular = true;
    /// Also write the mesh's narrow-band level set `surface` (meaningful for closed meshes).
    bool keepSdf = false;
    /// Refuse meshes whose estimated surface-voxel count exceeds this: the voxelizer peaks at
    /// about 64 bytes per voxel (2^28 voxels: 16 GiB).
    uint64_t maxVoxels = uint64_t(1) << 28;
};

/// @brief Voxelize @a mesh into the grids of a surface scene (docs/scene-contract.md, form (b)):
/// `normal` (vec3s, world-space unit normals, active on the surface voxels), `albedo` (float, or
/// vec3s when any material colour is not grey; only if the mesh has materials), `emission`
/// (likewise; only if something emits), `specular` (float or vec3s) and `roughness` (float) when
/// a material has `Ks` (and options.specular), `material_id` (Int32, background -1) when the
/// mesh has groups (OBJ `o` / `g`), and with keepSdf the level set `surface`.
/// @param warnings  if given, gets a line for each light that keeps no voxel of its own (an
///        emitting triangle of zero area; one whose every voxel is held by a light facing
///        another way), naming the first such triangle (1-based), its material and object
/// @throw openvdb::ValueError bad options, a mesh with non-finite points or no triangle of
///        non-zero area, or an estimated voxel count above maxVoxels (the message gives the
///        estimate and the voxel size that would fit)
/// @throw vdbrad::Cancelled if @a interrupt asks to stop
///
/// @code
/// vdbrad::VoxelizeOptions o; o.resolution = 256;
/// openvdb::GridPtrVec grids = vdbrad::voxelizeMesh(vdbrad::readMesh("room.obj"), o);
/// @endcode
openvdb::GridPtrVec voxelizeMesh(const TriangleMesh& mesh, const VoxelizeOptions& options,
    openvdb::util::NullInterrupter* interrupt = nullptr,
    std::vector<std::string>* warnings = nullptr);

/// The prefix of the `material_id` grid's metadata naming its ids (TriangleMesh::groups):
/// "vdbrad:material_name:3" holds the name of id 3.
constexpr const char* kMaterialNameMeta = "vdbrad:material_name:";

/// @brief The voxel size voxelizeMesh uses for @a mesh and @a options (world units).
double voxelizeVoxelSize(const TriangleMesh& mesh, const VoxelizeOptions& options);

/// @name Exact voxel tests (index space; exposed for the tests)
/// @{
/// True iff the closed cube [c - 1/2, c + 1/2] meets the closed triangle (a, b, c).
bool triangleMeetsVoxel(const openvdb::Vec3d& centre, const openvdb::Vec3d& a,
    const openvdb::Vec3d& b, const openvdb::Vec3d& c);
/// True iff one of the nine closed segments centre + s d, |s| <= 1/2, d an axis step or a face
/// diagonal (e_i +- e_j), meets the closed triangle.
bool triangleMeetsVoxelStar(const openvdb::Vec3d& centre, const openvdb::Vec3d& a,
    const openvdb::Vec3d& b, const openvdb::Vec3d& c);
/// Squared distance from @a p to the closed triangle (a, b, c).
double squaredDistanceToTriangle(const openvdb::Vec3d& p, const openvdb::Vec3d& a,
    const openvdb::Vec3d& b, const openvdb::Vec3d& c);
/// @}

} // namespace vdbrad
