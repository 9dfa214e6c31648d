#include "vdbrad/cloud/Ground.h"

#include <openvdb/openvdb.h>

#include <cmath>

namespace vdbrad {

GroundLayer::GroundLayer(const openvdb::CoordBBox& box, int up)
    : mUp(up), mLayer(box.min()[up] - 1)
{
    mAxis[0] = (up + 1) % 3;
    mAxis[1] = (up + 2) % 3;
    mMin = box.min();
    const openvdb::Coord dim = box.dim();
    mDim[0] = dim[mAxis[0]];
    mDim[1] = dim[mAxis[1]];
}

openvdb::Coord
GroundLayer::coord(size_t cell) const
{
    openvdb::Coord ijk = mMin;
    ijk[mUp] = mLayer;
    ijk[mAxis[0]] += int(cell / size_t(mDim[1]));
    ijk[mAxis[1]] += int(cell % size_t(mDim[1]));
    return ijk;
}

openvdb::CoordBBox
GroundLayer::bbox() const
{
    if (size() == 0) return openvdb::CoordBBox();
    return openvdb::CoordBBox(coord(0), coord(size() - 1));
}

int64_t
GroundLayer::cellBelow(const openvdb::Vec3d& p, const openvdb::Vec3d& t, bool periodic) const
{
    const openvdb::Vec3d q = p + t * ((double(mLayer) + 0.5 - p[mUp]) / t[mUp]);
    openvdb::Coord ijk;
    ijk[mUp] = mLayer;
    for (int a = 0; a < 2; ++a) {
        const int k = mAxis[a];
        // Voxel c spans [c - 1/2, c + 1/2) in index space.
        int64_t c = int64_t(std::floor(q[k] + 0.5)) - mMin[k];
        if (periodic) c = ((c % mDim[a]) + mDim[a]) % mDim[a];
        else if (c < 0 || c >= mDim[a]) return -1;
        ijk[k] = mMin[k] + int(c);
    }
    return int64_t(cell(ijk));
}

Cloud
GroundLayer::withGround(const Cloud& cloud, std::vector<uint32_t>* source) const
{
    const VoxelIndex& voxels = cloud.voxels();
    VoxelIndex::checkVoxelCount(uint64_t(voxels.size()) + uint64_t(size()));
    openvdb::MaskTree mask;
    {
        openvdb::tree::ValueAccessor<openvdb::MaskTree> acc(mask);
        for (const openvdb::Coord& ijk : voxels.coords()) acc.setValueOn(ijk);
        for (size_t c = 0; c < size(); ++c) acc.setValueOn(coord(c));
    }
    VoxelIndex all(mask);
    std::vector<uint32_t> from(all.size());
    std::vector<float> extinction(all.size(), 0.f);
    for (size_t i = 0; i < all.size(); ++i) {
        const openvdb::Coord& ijk = all.coord(i);
        if (contains(ijk)) {
            from[i] = kGround;
            continue;
        }
        from[i] = uint32_t(voxels.find(ijk));
        extinction[i] = cloud.extinction(from[i]);
    }
    // A ground cell's albedo is never read (CloudTransfer keeps the ground's own): 0 there.
    const Attribute& a = cloud.albedo();
    Attribute albedo(a.uniformValue());
    if (a.isRgb()) {
        std::vector<openvdb::Vec3f> v(all.size(), openvdb::Vec3f(0.f));
        for (size_t i = 0; i < v.size(); ++i) if (from[i] != kGround) v[i] = a.rgb(from[i]);
        albedo = Attribute::fromRgb(std::move(v));
    } else if (!a.isUniform()) {
        std::vector<float> v(all.size(), 0.f);
        for (size_t i = 0; i < v.size(); ++i) if (from[i] != kGround) v[i] = a.grey(from[i]);
        albedo = Attribute::fromGrey(std::move(v));
    }
    if (source) *source = std::move(from);
    return Cloud(cloud.transform().copy(), std::move(all), std::move(extinction),
        std::move(albedo), cloud.densityName());
}

std::vector<double>
groundEmission(const std::vector<float>& omega, const std::vector<double>& mu,
    const std::vector<float>& step)
{
    double total = 0.0;
    for (size_t d = 0; d < omega.size(); ++d) total += double(omega[d]) * mu[d];
    std::vector<double> gain(omega.size(), 0.0);
    if (!(total > 0.0)) return gain;
    // w_d / (Omega_d / step_d) = mu_d step_d / total: Omega_d cancels.
    for (size_t d = 0; d < omega.size(); ++d) gain[d] = mu[d] * double(step[d]) / total;
    return gain;
}

} // namespace vdbrad
