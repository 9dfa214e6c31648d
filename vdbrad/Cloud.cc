#include "vdbrad/Cloud.h"

#include "vdbrad/Errors.h"

#include <cmath>

namespace vdbrad {

Cloud::Cloud(openvdb::math::Transform::Ptr transform, VoxelIndex voxels,
    std::vector<float> extinction, Attribute albedo, std::string densityName)
    : mTransform(std::move(transform))
    , mVoxels(std::move(voxels))
    , mExtinction(std::move(extinction))
    , mAlbedo(std::move(albedo))
    , mDensityName(std::move(densityName))
{
}

size_t
Cloud::memUsage() const
{
    return mVoxels.size() * (sizeof(openvdb::Coord) + sizeof(float))
        + size_t(mVoxels.tree().memUsage()) + mAlbedo.memUsage();
}

Cloud
buildCloud(const openvdb::GridPtrVec& grids, const CloudOptions& options,
    openvdb::util::NullInterrupter* interrupt)
{
    if (!(options.extinctionScale > 0.f) || !std::isfinite(options.extinctionScale)) {
        OPENVDB_THROW(openvdb::ValueError, "extinction scale must be positive and finite, got "
            << options.extinctionScale);
    }
    if (!(options.defaultAlbedo >= 0.f && options.defaultAlbedo <= 1.f)) {
        OPENVDB_THROW(openvdb::ValueError, "albedo must be in [0, 1], got "
            << options.defaultAlbedo);
    }
    GridRoles roles = identifyRoles(grids, "", options.density);
    if (!options.albedoGrid) roles.albedo.reset();
    if (!roles.density) {
        // Simulators name their fields freely: name the fog volumes the file has.
        std::string fogs;
        for (const auto& g : grids) {
            if (g && g->getGridClass() == openvdb::GRID_FOG_VOLUME) {
                fogs += (fogs.empty() ? "" : ", ") + ("'" + g->getName() + "'");
            }
        }
        OPENVDB_THROW(openvdb::KeyError, "no cloud: expected a float grid named '"
            << options.density << "'" << (fogs.empty() ? "" : " (the file's fog volumes: "
            + fogs + "; choose one with --density NAME)"));
    }
    const auto& density = static_cast<const openvdb::FloatGrid&>(*roles.density);
    checkTransform(density);
    if (roles.albedo) checkSameTransform(*roles.albedo, density);
    if (density.activeVoxelCount() == 0) {
        OPENVDB_THROW(openvdb::ValueError, "density grid '" << density.getName()
            << "' has no active voxels");
    }

    VoxelIndex index(openvdb::MaskTree(density.tree(), false, openvdb::TopologyCopy()));
    if (openvdb::util::wasInterrupted(interrupt)) throw Cancelled("cloud build");

    // Density is validated through the same sampler as the attributes, then scaled; the scale
    // is applied in double so a huge scale overflows to a clear error rather than to inf.
    const Attribute sampled = Attribute::sample(density, index, names::kDensity, 0.f);
    std::vector<float> extinction(index.size());
    for (size_t i = 0; i < index.size(); ++i) {
        const double s = double(sampled.grey(i)) * options.extinctionScale;
        if (s > double(std::numeric_limits<float>::max())) {
            OPENVDB_THROW(openvdb::ValueError, "extinction at voxel " << formatCoord(index.coord(i))
                << " overflows: density " << sampled.grey(i) << " x scale "
                << options.extinctionScale);
        }
        extinction[i] = float(s);
    }
    Attribute albedo = roles.albedo
        ? Attribute::sample(*roles.albedo, index, names::kAlbedo, 0.f, 1.f)
        : Attribute(options.defaultAlbedo);
    return Cloud(density.transform().copy(), std::move(index), std::move(extinction),
        std::move(albedo), density.getName());
}

Cloud
tileCloud(const Cloud& cloud, const openvdb::Coord& copies, std::vector<uint32_t>* source)
{
    const VoxelIndex& voxels = cloud.voxels();
    const openvdb::CoordBBox box = voxels.bbox();
    const openvdb::Coord dim = box.dim();
    VoxelIndex::checkVoxelCount(uint64_t(voxels.size()) * uint64_t(copies.x())
        * uint64_t(copies.y()) * uint64_t(copies.z()));
    openvdb::MaskTree mask;
    openvdb::tree::ValueAccessor<openvdb::MaskTree> acc(mask);
    for (int a = 0; a < copies.x(); ++a) {
        for (int b = 0; b < copies.y(); ++b) {
            for (int c = 0; c < copies.z(); ++c) {
                const openvdb::Coord shift(a * dim.x(), b * dim.y(), c * dim.z());
                for (const openvdb::Coord& ijk : voxels.coords()) acc.setValueOn(ijk + shift);
            }
        }
    }
    VoxelIndex tiled(mask);
    std::vector<uint32_t> from(tiled.size());
    for (size_t i = 0; i < tiled.size(); ++i) {
        const openvdb::Coord d = tiled.coord(i) - box.min();
        const openvdb::Coord ijk = box.min()
            + openvdb::Coord(d.x() % dim.x(), d.y() % dim.y(), d.z() % dim.z());
        from[i] = uint32_t(voxels.find(ijk));
    }
    std::vector<float> extinction(tiled.size());
    for (size_t i = 0; i < tiled.size(); ++i) extinction[i] = cloud.extinction(from[i]);
    const Attribute& a = cloud.albedo();
    Attribute albedo(a.uniformValue());
    if (a.isRgb()) {
        std::vector<openvdb::Vec3f> v(tiled.size());
        for (size_t i = 0; i < v.size(); ++i) v[i] = a.rgb(from[i]);
        albedo = Attribute::fromRgb(std::move(v));
    } else if (!a.isUniform()) {
        std::vector<float> v(tiled.size());
        for (size_t i = 0; i < v.size(); ++i) v[i] = a.grey(from[i]);
        albedo = Attribute::fromGrey(std::move(v));
    }
    if (source) *source = std::move(from);
    return Cloud(cloud.transform().copy(), std::move(tiled), std::move(extinction),
        std::move(albedo), cloud.densityName());
}

} // namespace vdbrad
