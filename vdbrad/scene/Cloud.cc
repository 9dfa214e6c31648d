#include "vdbrad/scene/Cloud.h"

#include "vdbrad/core/Errors.h"

#include <cmath>

namespace vdbrad {

Cloud::Cloud(openvdb::math::Transform::Ptr transform, VoxelIndex voxels,
    std::vector<float> extinction, Attribute albedo, std::string densityName, Attribute emission)
    : mTransform(std::move(transform))
    , mVoxels(std::move(voxels))
    , mExtinction(std::move(extinction))
    , mAlbedo(std::move(albedo))
    , mDensityName(std::move(densityName))
    , mEmission(std::move(emission))
{
}

size_t
Cloud::memUsage() const
{
    return mVoxels.size() * (sizeof(openvdb::Coord) + sizeof(float))
        + size_t(mVoxels.tree().memUsage()) + mAlbedo.memUsage() + mEmission.memUsage();
}

namespace {

// CloudOptions::emission into cloud.mEmission (see the file comment of Cloud.h).
void
readEmission(Cloud& cloud, const openvdb::GridPtrVec& grids, const CloudOptions& options)
{
    const openvdb::Vec3f& colour = options.emissionColour;
    if (!(options.emissionScale >= 0.f) || !std::isfinite(options.emissionScale)
        || !(colour[0] >= 0.f && colour[1] >= 0.f && colour[2] >= 0.f)
        || !std::isfinite(colour[0] + colour[1] + colour[2])) {
        OPENVDB_THROW(openvdb::ValueError, "emission scale and colour must be >= 0 and finite, "
            "got " << options.emissionScale << " and " << colour);
    }
    const std::string name = options.emission.empty() ? std::string(names::kFlame)
                                                      : options.emission;
    const openvdb::GridBase::ConstPtr found = findGrid(grids, name);
    if (!found) {
        if (options.emission.empty()) return;   // nothing burns
        OPENVDB_THROW(openvdb::KeyError, "no emission grid named '" << name << "'");
    }
    if (!found->isType<openvdb::FloatGrid>() && !found->isType<openvdb::DoubleGrid>()) {
        OPENVDB_THROW(openvdb::TypeError, "grid '" << name << "' (emission) has type "
            << found->valueType() << ", expected float or double");
    }
    const auto grid = openvdb::gridConstPtrCast<openvdb::FloatGrid>(singlePrecision(found));
    checkSameTransform(*grid, *findGrid(grids, cloud.densityName()));
    const Attribute strength = Attribute::sample(*grid, cloud.voxels(), name, 0.f);
    const bool grey = colour[0] == colour[1] && colour[1] == colour[2];
    std::vector<float> g(grey ? cloud.size() : 0);
    std::vector<openvdb::Vec3f> rgb(grey ? 0 : cloud.size());
    size_t kept = 0;
    for (size_t i = 0; i < cloud.size(); ++i) {
        // The medium emits through its extinction: none where it has none.
        const double e = cloud.extinction(i) > 0.f
            ? double(strength.grey(i)) * double(options.emissionScale) : 0.0;
        if (e > double(std::numeric_limits<float>::max()) / std::max(1.f, colour[0] + colour[1]
                + colour[2])) {
            OPENVDB_THROW(openvdb::ValueError, "emission at voxel "
                << formatCoord(cloud.voxels().coord(i)) << " overflows: " << strength.grey(i)
                << " x scale " << options.emissionScale);
        }
        if (e > 0.0) ++kept;
        if (grey) g[i] = float(e) * colour[0];
        else rgb[i] = openvdb::Vec3f(float(e)) * colour;
    }
    size_t emitting = 0;
    for (auto it = grid->cbeginValueOn(); it; ++it) {
        if (*it > 0.f) emitting += it.isVoxelValue() ? 1 : size_t(it.getVoxelCount());
    }
    cloud.setEmission(grey ? Attribute::fromGrey(std::move(g)) : Attribute::fromRgb(std::move(rgb)),
        name, emitting > kept ? emitting - kept : 0);
}

} // namespace

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
    Cloud cloud(density.transform().copy(), std::move(index), std::move(extinction),
        std::move(albedo), density.getName());
    readEmission(cloud, grids, options);
    return cloud;
}

void
recordEmission(openvdb::GridBase& result, const Cloud& cloud, const CloudOptions& options)
{
    if (cloud.emissionName().empty()) return;
    result.insertMeta("vdbrad:emission", openvdb::StringMetadata(cloud.emissionName()));
    result.insertMeta("vdbrad:emission_scale", openvdb::FloatMetadata(options.emissionScale));
    result.insertMeta("vdbrad:emission_color", openvdb::Vec3SMetadata(options.emissionColour));
}

CloudOptions
emissionAsSolved(const openvdb::GridBase& result, CloudOptions options)
{
    const auto name = result.getMetadata<openvdb::StringMetadata>("vdbrad:emission");
    const auto scale = result.getMetadata<openvdb::FloatMetadata>("vdbrad:emission_scale");
    const auto colour = result.getMetadata<openvdb::Vec3SMetadata>("vdbrad:emission_color");
    if (name && scale && colour) {
        options.emission = name->value();
        options.emissionScale = scale->value();
        options.emissionColour = colour->value();
    }
    return options;
}

namespace {

// The voxels @a index of a cloud each of which is @a cloud's voxel from[i] (kNoCloudVoxel: an
// empty one), with their medium and emission.
Cloud
remapped(const Cloud& cloud, VoxelIndex index, std::vector<uint32_t> from,
    std::vector<uint32_t>* source)
{
    std::vector<float> extinction(index.size(), 0.f);
    for (size_t i = 0; i < index.size(); ++i) {
        if (from[i] != kNoCloudVoxel) extinction[i] = cloud.extinction(from[i]);
    }
    Attribute albedo = cloud.albedo().subset(from), emission = cloud.emission().subset(from);
    if (source) *source = std::move(from);
    Cloud result(cloud.transform().copy(), std::move(index), std::move(extinction),
        std::move(albedo), cloud.densityName());
    result.setEmission(std::move(emission), cloud.emissionName(), cloud.lostEmitters());
    return result;
}

} // namespace

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
    return remapped(cloud, std::move(tiled), std::move(from), source);
}

std::array<bool, 3>
uniformAxes(const Cloud& cloud, int up)
{
    const VoxelIndex& voxels = cloud.voxels();
    const openvdb::CoordBBox box = voxels.bbox();
    const Attribute &albedo = cloud.albedo(), &emission = cloud.emission();
    std::array<bool, 3> uniform{};
    for (int k = 0; k < 3; ++k) {
        if (k == up || box.dim()[k] < 2) continue;
        bool same = true;
        for (size_t i = 0; i < voxels.size() && same; ++i) {
            openvdb::Coord next = voxels.coord(i);
            next[k] = next[k] == box.max()[k] ? box.min()[k] : next[k] + 1;
            const int64_t j = voxels.find(next);
            same = j >= 0 && cloud.extinction(i) == cloud.extinction(size_t(j))
                && albedo.rgb(i) == albedo.rgb(size_t(j))
                && emission.rgb(i) == emission.rgb(size_t(j));
        }
        uniform[size_t(k)] = same;
    }
    return uniform;
}

Cloud
sliceCloud(const Cloud& cloud, const std::array<bool, 3>& axes)
{
    const VoxelIndex& voxels = cloud.voxels();
    const openvdb::CoordBBox box = voxels.bbox();
    openvdb::MaskTree mask;
    openvdb::tree::ValueAccessor<openvdb::MaskTree> acc(mask);
    for (const openvdb::Coord& ijk : voxels.coords()) {
        bool first = true;
        for (int k = 0; k < 3; ++k) first = first && (!axes[size_t(k)] || ijk[k] == box.min()[k]);
        if (first) acc.setValueOn(ijk);
    }
    VoxelIndex slice(mask);
    std::vector<uint32_t> from(slice.size());
    for (size_t i = 0; i < slice.size(); ++i) from[i] = uint32_t(voxels.find(slice.coord(i)));
    return remapped(cloud, std::move(slice), std::move(from), nullptr);
}

Cloud
filledBox(const Cloud& cloud, std::vector<uint32_t>* source)
{
    const VoxelIndex& voxels = cloud.voxels();
    const openvdb::CoordBBox box = voxels.bbox();
    VoxelIndex::checkVoxelCount(box.volume());
    openvdb::MaskTree mask;
    mask.denseFill(box, true, true);
    VoxelIndex all(mask);
    std::vector<uint32_t> from(all.size());
    for (size_t i = 0; i < all.size(); ++i) {
        const int64_t f = voxels.find(all.coord(i));
        from[i] = f < 0 ? kNoCloudVoxel : uint32_t(f);
    }
    return remapped(cloud, std::move(all), std::move(from), source);
}

} // namespace vdbrad
