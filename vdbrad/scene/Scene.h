// Scene: the surface voxels of a `.vdb` file, ready for the radiosity sweeps.
//
// Data path: grids --identifyRoles--> surface grid (level set or `normal`) --> VoxelIndex
// (compact, leaf order) --> per-voxel arrays: index-space unit normal, albedo, emission.
// Only what the input has is stored: a grey scene has no RGB arrays, a scene without an
// `emission` grid has no emission array (Attribute::Uniform 0), a scene without an `albedo` grid
// has a uniform albedo (SceneOptions::defaultAlbedo).
//
// Memory: 12 bytes (coord) + 12 (normal) + 4 (index tree, amortised) per voxel, plus 4 or 12 per
// per-voxel attribute.
#pragma once

#include "vdbrad/core/Attribute.h"
#include "vdbrad/core/GridContract.h"
#include "vdbrad/core/VoxelIndex.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <string>
#include <vector>

namespace vdbrad {

struct SceneOptions
{
    /// Grid to use as the surface; empty: `normal` if present, else the only level set.
    std::string surface;
    /// Albedo of every voxel when the file has no `albedo` grid, in [0, 1].
    float defaultAlbedo = 0.5f;
    /// Roughness of glossy voxels when the file has a `specular` grid and no `roughness` grid,
    /// in [kMinRoughness (core/Constants.h), 1].
    float defaultRoughness = 0.5f;
    /// Level sets only: 26 (default) or 6, the connectivity the extracted surface blocks
    /// (see SurfaceExtraction.h).
    int separation = 26;
};

class Scene
{
public:
    Scene() = default;
    Scene(openvdb::math::Transform::Ptr transform, VoxelIndex voxels,
        std::vector<openvdb::Vec3f> normals, Attribute albedo, Attribute emission,
        std::string surfaceName, GridRoles::SurfaceKind kind,
        Attribute emissionArea = Attribute(0.f));

    size_t size() const { return mVoxels.size(); }
    const VoxelIndex& voxels() const { return mVoxels; }
    /// The input's transform (index -> world); the solver works in index space.
    const openvdb::math::Transform& transform() const { return *mTransform; }
    openvdb::math::Transform::Ptr transformPtr() const { return mTransform; }
    /// Edge length of a voxel in world units.
    double voxelSize() const { return mTransform->voxelSize()[0]; }

    /// Unit outward normal of voxel @a i in index space (equal to world space unless the
    /// transform rotates).
    const openvdb::Vec3f& normal(size_t i) const { return mNormals[i]; }
    const std::vector<openvdb::Vec3f>& normals() const { return mNormals; }
    /// World-space unit normal of voxel @a i.
    openvdb::Vec3f worldNormal(size_t i) const;

    const Attribute& albedo() const { return mAlbedo; }
    const Attribute& emission() const { return mEmission; }
    /// True if any colour attribute is RGB: the solution is then RGB too.
    bool isRgb() const { return mAlbedo.isRgb() || mEmission.isRgb() || mSpecular.isRgb(); }
    /// False if nothing emits: the solution is then zero everywhere.
    bool hasEmission() const { return !mEmission.isZero(); }
    /// Emitting area inside each voxel, in voxel faces (an `emission_area` grid, world units^2,
    /// over the voxel size squared): exact direct light gives each emitter patch the power
    /// emission x this area (Emitters.h). hasEmissionArea() is false when the input has none.
    const Attribute& emissionArea() const { return mEmissionArea; }
    bool hasEmissionArea() const { return !mEmissionArea.isUniform(); }

    /// Glossy lobes (Brdf.h): reflectance ks per voxel (Uniform 0 when the input has no
    /// `specular` grid: a diffuse scene stores nothing) and roughness. isGlossy(): some voxel
    /// has ks > 0.
    const Attribute& specular() const { return mSpecular; }
    const Attribute& roughness() const { return mRoughness; }
    bool isGlossy() const { return !mSpecular.isZero(); }
    /// @brief Give the voxels glossy lobes (arrays in Scene order, or uniform values).
    /// @throw openvdb::ValueError if a value is not finite, ks < 0, albedo + ks > 1 in some
    ///        channel, or roughness is outside [kMinRoughness (core/Constants.h), 1] (naming the voxel)
    void setGloss(Attribute specular, Attribute roughness);
    /// Glossy voxels whose `roughness` was below kMinRoughness (core/Constants.h) and was raised to it.
    size_t raisedRoughness() const { return mRaisedRoughness; }

    /// Name of the grid the surface came from, and how.
    const std::string& surfaceName() const { return mSurfaceName; }
    GridRoles::SurfaceKind surfaceKind() const { return mKind; }

    /// Bytes held by the arrays (not counting the input grids).
    size_t memUsage() const;
    /// @brief The scene of the voxels @a voxels (increasing indices into this one) alone: one
    /// rank's slab of a data-distributed solve (SlabDistribution.h). Its voxel i is
    /// voxels[i] of this one.
    Scene subset(const std::vector<uint32_t>& voxels) const;

private:
    openvdb::math::Transform::Ptr mTransform;
    VoxelIndex mVoxels;
    std::vector<openvdb::Vec3f> mNormals;
    Attribute mAlbedo, mEmission, mEmissionArea;
    Attribute mSpecular, mRoughness{0.5f};
    size_t mRaisedRoughness = 0;
    friend Scene buildScene(const openvdb::GridPtrVec&, const SceneOptions&,
        openvdb::util::NullInterrupter*);
    std::string mSurfaceName;
    GridRoles::SurfaceKind mKind = GridRoles::SurfaceKind::None;
};

/// @brief Build the surface scene of a file's grids (docs/scene-contract.md).
/// @throw openvdb::KeyError   no surface grid (neither a level set nor `normal`)
/// @throw openvdb::TypeError  a contract grid has the wrong value type
/// @throw openvdb::ValueError empty surface, NaN/Inf values, zero-length normals, albedo outside
///        [0, 1], negative emission, mismatched or unsupported transforms
/// @throw vdbrad::Cancelled   if @a interrupt asks to stop
///
/// @code
/// openvdb::io::File file("cornell.vdb"); file.open(false);
/// vdbrad::Scene scene = vdbrad::buildScene(*file.getGrids());
/// std::cout << scene.size() << " surface voxels\n";
/// @endcode
Scene buildScene(const openvdb::GridPtrVec& grids, const SceneOptions& options = SceneOptions(),
    openvdb::util::NullInterrupter* interrupt = nullptr);

} // namespace vdbrad
