#include "vdbrad/core/Attribute.h"

#include "vdbrad/core/Checkpoint.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <sstream>

namespace vdbrad {

std::string
formatCoord(const openvdb::Coord& ijk)
{
    std::ostringstream os;
    os << "(" << ijk.x() << ", " << ijk.y() << ", " << ijk.z() << ")";
    return os.str();
}

bool
Attribute::isZero() const
{
    switch (mStorage) {
        case Storage::Uniform: return mUniform == 0.f;
        case Storage::Grey:
            for (float v : mGrey) if (v != 0.f) return false;
            return true;
        case Storage::Rgb:
            for (const auto& c : mRgb) if (c[0] != 0.f || c[1] != 0.f || c[2] != 0.f) return false;
            return true;
    }
    return true;
}

Attribute
Attribute::subset(const std::vector<uint32_t>& at) const
{
    Attribute a;   // not a copy: a slab's arrays would keep the whole scene's capacity
    a.mStorage = mStorage;
    a.mUniform = mUniform;
    if (mStorage == Storage::Grey) {
        a.mGrey.resize(at.size());
        for (size_t k = 0; k < at.size(); ++k) a.mGrey[k] = at[k] == kNone ? 0.f : mGrey[at[k]];
    } else if (mStorage == Storage::Rgb) {
        a.mRgb.resize(at.size());
        for (size_t k = 0; k < at.size(); ++k) {
            a.mRgb[k] = at[k] == kNone ? openvdb::Vec3f(0.f) : mRgb[at[k]];
        }
    }
    return a;
}

Attribute
Attribute::fromGrey(std::vector<float> values)
{
    Attribute a;
    a.mStorage = Storage::Grey;
    a.mGrey = std::move(values);
    return a;
}

Attribute
Attribute::fromRgb(std::vector<openvdb::Vec3f> values)
{
    Attribute a;
    a.mStorage = Storage::Rgb;
    a.mRgb = std::move(values);
    return a;
}

namespace {

inline float channel(float v, int) { return v; }
inline float channel(const openvdb::Vec3f& v, int c) { return v[c]; }

// Samples one value type; Check is called on every channel and throws on a bad value.
template<typename GridT, typename ValueT>
std::vector<ValueT>
sampleGrid(const GridT& grid, const VoxelIndex& index, const std::string& name, float lo, float hi)
{
    std::vector<ValueT> out(index.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, index.leafCount()),
        [&](const tbb::blocked_range<size_t>& r) {
            auto acc = grid.getConstAccessor();
            for (size_t n = r.begin(); n != r.end(); ++n) {
                for (size_t i = index.leafBegin(n); i < index.leafBegin(n + 1); ++i) {
                    const ValueT v = acc.getValue(index.coord(i));
                    for (int c = 0; c < openvdb::VecTraits<ValueT>::Size; ++c) {
                        const float x = channel(v, c);
                        if (!std::isfinite(x) || x < lo || x > hi) {
                            std::ostringstream os;
                            os << name << " at voxel " << formatCoord(index.coord(i)) << " is " << x;
                            if (std::isfinite(x)) {
                                os << ", outside [" << lo << ", ";
                                if (hi == std::numeric_limits<float>::max()) os << "inf)";
                                else os << hi << "]";
                            }
                            OPENVDB_THROW(openvdb::ValueError, os.str());
                        }
                    }
                    out[i] = v;
                }
            }
        });
    return out;
}

} // namespace

Attribute
Attribute::sample(const openvdb::GridBase& grid, const VoxelIndex& index, const std::string& name,
    float lo, float hi)
{
    if (const auto* g = dynamic_cast<const openvdb::FloatGrid*>(&grid)) {
        return fromGrey(sampleGrid<openvdb::FloatGrid, float>(*g, index, name, lo, hi));
    }
    if (const auto* g = dynamic_cast<const openvdb::Vec3SGrid*>(&grid)) {
        return fromRgb(sampleGrid<openvdb::Vec3SGrid, openvdb::Vec3f>(*g, index, name, lo, hi));
    }
    OPENVDB_THROW(openvdb::TypeError, "grid '" << grid.getName() << "' (" << name << ") has type "
        << grid.valueType() << ", expected float or vec3s");
}

uint64_t
Attribute::hash(uint64_t h) const
{
    const int64_t kind[1] = {int64_t(mStorage)};
    h = hashBytes(kind, sizeof kind, h);
    h = hashBytes(&mUniform, sizeof mUniform, h);
    h = hashBytes(mGrey.data(), mGrey.size() * sizeof(float), h);
    return hashBytes(mRgb.data(), mRgb.size() * sizeof(openvdb::Vec3f), h);
}

} // namespace vdbrad
