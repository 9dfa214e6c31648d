#include "vdbrad/sweep/LineSweep.h"

#include "vdbrad/sweep/VectorClones.h"

namespace vdbrad {

namespace {

// The same products and sums, in the same order, as openvdb::Vec3f::dot: every clone gives the
// bits the scalar sweep would.
VDBRAD_VECTOR_CLONES void
dotAll(const openvdb::Vec3f* normals, size_t n, float sx, float sy, float sz, float* out)
{
    for (size_t k = 0; k < n; ++k) {
        out[k] = sx * normals[k][0] + sy * normals[k][1] + sz * normals[k][2];
    }
}

} // namespace

void
LineSweep::facing(const openvdb::Coord& sigma, std::vector<float>& facing) const
{
    facing.resize(mNormals.size());
    this->facing(sigma, 0, uint32_t(mNormals.size()), facing.data());
}

void
LineSweep::facing(const openvdb::Coord& sigma, uint32_t begin, uint32_t end, float* out) const
{
    dotAll(mNormals.data() + begin, end - begin, float(sigma.x()), float(sigma.y()),
        float(sigma.z()), out);
}

} // namespace vdbrad
