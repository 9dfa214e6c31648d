#include "vdbrad/scene/Scene.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/scene/SurfaceExtraction.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

namespace vdbrad {

Scene::Scene(openvdb::math::Transform::Ptr transform, VoxelIndex voxels,
    std::vector<openvdb::Vec3f> normals, Attribute albedo, Attribute emission,
    std::string surfaceName, GridRoles::SurfaceKind kind, Attribute emissionArea)
    : mTransform(std::move(transform))
    , mVoxels(std::move(voxels))
    , mNormals(std::move(normals))
    , mAlbedo(std::move(albedo))
    , mEmission(std::move(emission))
    , mEmissionArea(std::move(emissionArea))
    , mSurfaceName(std::move(surfaceName))
    , mKind(kind)
{
}

Scene
Scene::subset(const std::vector<uint32_t>& voxels) const
{
    openvdb::MaskTree mask;
    for (const uint32_t i : voxels) mask.setValueOn(mVoxels.coord(i));
    VoxelIndex index(mask);
    // An index numbers voxels in tree order, which a subset's tree keeps.
    for (size_t k = 0; k < voxels.size(); ++k) {
        if (index.coord(k) != mVoxels.coord(voxels[k])) {
            OPENVDB_THROW(openvdb::ValueError, "Scene::subset: voxels not in increasing order");
        }
    }
    std::vector<openvdb::Vec3f> normals(voxels.size());
    for (size_t k = 0; k < voxels.size(); ++k) normals[k] = mNormals[voxels[k]];
    Scene s(mTransform, std::move(index), std::move(normals), mAlbedo.subset(voxels),
        mEmission.subset(voxels), mSurfaceName, mKind, mEmissionArea.subset(voxels));
    s.mSpecular = mSpecular.subset(voxels);
    s.mRoughness = mRoughness.subset(voxels);
    s.mRaisedRoughness = 0;
    return s;
}

openvdb::Vec3f
Scene::worldNormal(size_t i) const
{
    // Normals are covariant: index -> world applies the inverse Jacobian transpose.
    const openvdb::Vec3d n = mTransform->baseMap()->applyIJT(openvdb::Vec3d(mNormals[i]));
    return openvdb::Vec3f(n.unit());
}

size_t
Scene::memUsage() const
{
    return mVoxels.size() * (sizeof(openvdb::Coord) + sizeof(openvdb::Vec3f))
        + size_t(mVoxels.tree().memUsage()) + mAlbedo.memUsage() + mEmission.memUsage()
        + mEmissionArea.memUsage() + mSpecular.memUsage() + mRoughness.memUsage();
}

namespace {

// Index-space unit normals from a `normal` grid of world-space vectors.
std::vector<openvdb::Vec3f>
normalGridNormals(const openvdb::Vec3SGrid& grid, const VoxelIndex& index)
{
    const openvdb::math::MapBase::ConstPtr map = grid.transform().baseMap();
    std::vector<openvdb::Vec3f> normals(index.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, index.leafCount()),
        [&](const tbb::blocked_range<size_t>& r) {
            auto acc = grid.getConstAccessor();
            for (size_t n = r.begin(); n != r.end(); ++n) {
                for (size_t i = index.leafBegin(n); i < index.leafBegin(n + 1); ++i) {
                    const openvdb::Vec3f w = acc.getValue(index.coord(i));
                    const double len = w.length();
                    if (!std::isfinite(len) || len < 1e-6) {
                        OPENVDB_THROW(openvdb::ValueError, "normal at voxel "
                            << formatCoord(index.coord(i)) << " is " << w
                            << (std::isfinite(len) ? " (zero length)" : " (not finite)"));
                    }
                    // World -> index for a covariant vector is the Jacobian transpose.
                    normals[i] = openvdb::Vec3f(map->applyJT(openvdb::Vec3d(w)).unit());
                }
            }
        });
    return normals;
}

} // namespace

void
Scene::setGloss(Attribute specular, Attribute roughness)
{
    const size_t n = size();
    for (size_t i = 0; i < n; ++i) {
        const openvdb::Vec3f ks = specular.rgb(i), rho = mAlbedo.rgb(i);
        const float r = roughness.grey(i);
        for (int c = 0; c < 3; ++c) {
            if (!std::isfinite(ks[c]) || ks[c] < 0.f) {
                OPENVDB_THROW(openvdb::ValueError, "specular at voxel "
                    << formatCoord(mVoxels.coord(i)) << " is " << ks[c]
                    << " (must be finite and >= 0)");
            }
            // A lobe and the diffuse part share the light a voxel receives: more than all of
            // it would create energy (a closed box would diverge).
            if (rho[c] + ks[c] > 1.f + 1e-6f) {
                OPENVDB_THROW(openvdb::ValueError, "albedo + specular at voxel "
                    << formatCoord(mVoxels.coord(i)) << " is " << rho[c] + ks[c]
                    << " (must be <= 1)");
            }
        }
        if (!(r >= float(kMinRoughness) && r <= 1.f)) {
            OPENVDB_THROW(openvdb::ValueError, "roughness at voxel "
                << formatCoord(mVoxels.coord(i)) << " is " << r << " (must be in ["
                << kMinRoughness << ", 1])");
        }
        if (specular.isUniform() && roughness.isUniform()) break;   // one value for all
    }
    mSpecular = std::move(specular);
    mRoughness = std::move(roughness);
}

Scene
buildScene(const openvdb::GridPtrVec& grids, const SceneOptions& options,
    openvdb::util::NullInterrupter* interrupt)
{
    if (!(options.defaultAlbedo >= 0.f && options.defaultAlbedo <= 1.f)) {
        OPENVDB_THROW(openvdb::ValueError, "albedo must be in [0, 1], got "
            << options.defaultAlbedo);
    }
    const GridRoles roles = identifyRoles(grids, options.surface);
    if (!roles.surface) {
        OPENVDB_THROW(openvdb::KeyError, "no surface: expected a level-set float grid or a vec3s "
            "grid named 'normal'");
    }
    const openvdb::GridBase& surface = *roles.surface;
    checkTransform(surface);
    if (surface.activeVoxelCount() == 0) {
        OPENVDB_THROW(openvdb::ValueError, "surface grid '" << surface.getName()
            << "' has no active voxels");
    }
    for (const auto& g : {roles.albedo, roles.emission, roles.emissionArea, roles.specular,
             roles.roughness}) {
        if (g) checkSameTransform(*g, surface);
    }

    VoxelIndex index;
    std::vector<openvdb::Vec3f> normals;
    if (roles.surfaceKind == GridRoles::SurfaceKind::LevelSet) {
        const auto& ls = static_cast<const openvdb::FloatGrid&>(surface);
        openvdb::MaskTree::Ptr mask = extractSurfaceVoxels(ls, options.separation, interrupt);
        index = VoxelIndex(*mask);
        if (index.empty()) {
            OPENVDB_THROW(openvdb::ValueError, "level set '" << surface.getName()
                << "' has no zero crossing: no surface voxels");
        }
        normals = levelSetNormals(ls, index);
    } else {
        const auto& ng = static_cast<const openvdb::Vec3SGrid&>(surface);
        index = VoxelIndex(openvdb::MaskTree(ng.tree(), false, openvdb::TopologyCopy()));
        normals = normalGridNormals(ng, index);
    }
    if (openvdb::util::wasInterrupted(interrupt)) throw Cancelled("scene build");

    Attribute albedo = roles.albedo
        ? Attribute::sample(*roles.albedo, index, names::kAlbedo, 0.f, 1.f)
        : Attribute(options.defaultAlbedo);
    Attribute emission = roles.emission
        ? Attribute::sample(*roles.emission, index, names::kEmission, 0.f)
        : Attribute(0.f);

    // In voxel faces, as the solver measures areas.
    Attribute emissionArea(0.f);
    if (roles.emissionArea) {
        const Attribute world = Attribute::sample(*roles.emissionArea, index,
            names::kEmissionArea, 0.f);
        const double face = surface.transform().voxelSize()[0] * surface.transform().voxelSize()[0];
        std::vector<float> faces(index.size());
        for (size_t i = 0; i < faces.size(); ++i) faces[i] = float(world.grey(i) / face);
        emissionArea = Attribute::fromGrey(std::move(faces));
    }

    if (roles.roughness && !roles.specular) {
        OPENVDB_THROW(openvdb::ValueError, "a 'roughness' grid needs a 'specular' grid (the "
            "glossy lobe's reflectance)");
    }
    if (!(options.defaultRoughness >= float(kMinRoughness)
            && options.defaultRoughness <= 1.f)) {
        OPENVDB_THROW(openvdb::ValueError, "roughness must be in [" << kMinRoughness
            << ", 1], got " << options.defaultRoughness);
    }
    Scene scene(surface.transform().copy(), std::move(index), std::move(normals),
        std::move(albedo), std::move(emission), surface.getName(), roles.surfaceKind,
        std::move(emissionArea));
    if (roles.specular) {
        Attribute specular = Attribute::sample(*roles.specular, scene.voxels(), names::kSpecular,
            0.f, 1.f);
        Attribute roughness = roles.roughness
            ? Attribute::sample(*roles.roughness, scene.voxels(), names::kRoughness, 0.f, 1.f)
            : Attribute(options.defaultRoughness);
        // Files write roughness 0 for mirrors; no control-point grid resolves lobes sharper
        // than kMinRoughness, so those are raised to it and counted (the tool says so).
        if (!roughness.isUniform()) {
            std::vector<float> r(scene.size());
            for (size_t i = 0; i < r.size(); ++i) {
                r[i] = roughness.grey(i);
                if (r[i] < float(kMinRoughness)) {
                    r[i] = float(kMinRoughness);
                    const openvdb::Vec3f ks = specular.rgb(i);
                    if (ks[0] > 0.f || ks[1] > 0.f || ks[2] > 0.f) ++scene.mRaisedRoughness;
                }
            }
            roughness = Attribute::fromGrey(std::move(r));
        }
        if (!specular.isZero()) scene.setGloss(std::move(specular), std::move(roughness));
    }
    return scene;
}

} // namespace vdbrad
