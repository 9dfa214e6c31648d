#include "vdbrad/cloud/FogSurfaces.h"

#include "vdbrad/core/Checkpoint.h"

#include <algorithm>
#include <cmath>

namespace vdbrad {

FogSurfaces::FogSurfaces(const Scene& scene, int channel)
    : mScene(scene), mChannel(channel)
{
    const bool rgb = scene.isRgb();
    if (channel < 0 || channel > (rgb ? 2 : 0)) {
        OPENVDB_THROW(openvdb::ValueError, "surface channel " << channel << " of a "
            << (rgb ? "RGB" : "grey") << " scene");
    }
    const size_t n = scene.size();
    mNormal = scene.normals();
    mAlbedo.resize(n);
    mEmission.resize(n);
    const Attribute& a = scene.albedo();
    const Attribute& e = scene.emission();
    for (size_t s = 0; s < n; ++s) {
        mAlbedo[s] = a.isRgb() ? a.rgb(s)[channel] : a.grey(s);
        mEmission[s] = e.isRgb() ? e.rgb(s)[channel] : e.grey(s);
    }
}

Cloud
FogSurfaces::merged(const Cloud& cloud, std::vector<uint32_t>& fromCloud,
    std::vector<uint32_t>& surfaceOf) const
{
    if (!(cloud.transform() == mScene.transform())) {
        OPENVDB_THROW(openvdb::ValueError, "the surface scene and the density grid must have "
            "the same transform (voxel size and placement)");
    }
    const VoxelIndex& medium = cloud.voxels();
    const VoxelIndex& surface = mScene.voxels();
    VoxelIndex::checkVoxelCount(uint64_t(medium.size()) + uint64_t(surface.size()));
    openvdb::MaskTree mask;
    {
        openvdb::tree::ValueAccessor<openvdb::MaskTree> acc(mask);
        for (const openvdb::Coord& ijk : medium.coords()) acc.setValueOn(ijk);
        for (const openvdb::Coord& ijk : surface.coords()) acc.setValueOn(ijk);
    }
    VoxelIndex all(mask);
    fromCloud.assign(all.size(), kNone);
    surfaceOf.assign(all.size(), kNone);
    std::vector<float> extinction(all.size(), 0.f), albedo(all.size(), 0.f);
    const Attribute& a = cloud.albedo();
    for (size_t i = 0; i < all.size(); ++i) {
        const openvdb::Coord& ijk = all.coord(i);
        const int32_t s = surface.find(ijk);
        if (s >= 0) {
            surfaceOf[i] = uint32_t(s);
            continue;
        }
        const uint32_t c = uint32_t(medium.find(ijk));
        fromCloud[i] = c;
        extinction[i] = cloud.extinction(c);
        albedo[i] = a.grey(c);
    }
    return Cloud(cloud.transform().copy(), std::move(all), std::move(extinction),
        a.isUniform() ? Attribute(a.uniformValue()) : Attribute::fromGrey(std::move(albedo)),
        cloud.densityName());
}

std::vector<double>
FogSurfaces::normalisers(const std::vector<openvdb::Vec3d>& units,
    const std::vector<float>& omega) const
{
    std::vector<double> Z(size(), 0.0);
    for (size_t s = 0; s < Z.size(); ++s) {
        const openvdb::Vec3d n(mNormal[s]);
        double z = 0.0;
        for (size_t d = 0; d < units.size(); ++d) z += double(omega[d]) * std::abs(units[d].dot(n));
        Z[s] = z;
    }
    return Z;
}

uint64_t
FogSurfaces::hash(uint64_t seed) const
{
    uint64_t h = hashBytes(mNormal.data(), mNormal.size() * sizeof(openvdb::Vec3f), seed);
    h = hashBytes(mAlbedo.data(), mAlbedo.size() * sizeof(float), h);
    return hashBytes(mEmission.data(), mEmission.size() * sizeof(float), h);
}

} // namespace vdbrad
