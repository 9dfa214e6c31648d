// Attribute: one per-voxel quantity (albedo, emission, ...) stored only as wide as the input needs.
//
// A grey scene must not pay for RGB arrays, and a scene without an `emission` grid must not pay
// for an emission array at all. An Attribute is therefore one of
//   Uniform - a single value for every voxel (a command-line default, or "absent" = 0),
//   Grey    - one float per voxel (a FloatGrid input),
//   Rgb     - one Vec3f per voxel (a Vec3f input).
// Arrays use the numbering of the VoxelIndex they were sampled on.
#pragma once

#include "vdbrad/core/VoxelIndex.h"

#include <openvdb/openvdb.h>

#include <limits>
#include <string>
#include <vector>

namespace vdbrad {

class Attribute
{
public:
    enum class Storage { Uniform, Grey, Rgb };

    /// The same value @a v for every voxel.
    explicit Attribute(float v = 0.f) : mUniform(v) {}

    Storage storage() const { return mStorage; }
    bool isUniform() const { return mStorage == Storage::Uniform; }
    bool isRgb() const { return mStorage == Storage::Rgb; }
    /// True if every voxel's value is zero in every channel.
    bool isZero() const;

    /// Value of voxel @a i; for an RGB attribute, grey() is the channel mean.
    float grey(size_t i) const
    {
        switch (mStorage) {
            case Storage::Uniform: return mUniform;
            case Storage::Grey: return mGrey[i];
            case Storage::Rgb: break;
        }
        const openvdb::Vec3f& c = mRgb[i];
        return (c[0] + c[1] + c[2]) / 3.f;
    }
    /// Value of voxel @a i as RGB (grey values replicated).
    openvdb::Vec3f rgb(size_t i) const
    {
        switch (mStorage) {
            case Storage::Uniform: return openvdb::Vec3f(mUniform);
            case Storage::Grey: return openvdb::Vec3f(mGrey[i]);
            case Storage::Rgb: break;
        }
        return mRgb[i];
    }
    float uniformValue() const { return mUniform; }
    /// FNV-1a hash of the values (and how they are stored), continuing from @a seed: part of
    /// a checkpoint's fingerprint.
    uint64_t hash(uint64_t seed) const;
    const std::vector<float>& greyArray() const { return mGrey; }
    const std::vector<openvdb::Vec3f>& rgbArray() const { return mRgb; }

    /// Bytes held by the per-voxel arrays.
    size_t memUsage() const
    {
        return mGrey.capacity() * sizeof(float) + mRgb.capacity() * sizeof(openvdb::Vec3f);
    }

    /// @brief Sample @a grid (a FloatGrid or Vec3SGrid) at every voxel of @a index.
    /// The value at a voxel is the grid's value there, active or not (its background where it
    /// stores nothing), as OpenVDB's samplers read it.
    /// @param name   the grid's role, used in error messages ("albedo", "emission")
    /// @param lo,hi  valid closed range of every channel
    /// @throw openvdb::TypeError  if the grid is neither float nor Vec3f
    /// @throw openvdb::ValueError naming the first offending voxel if a value is NaN, infinite or
    ///        outside [lo, hi]
    static Attribute sample(const openvdb::GridBase& grid, const VoxelIndex& index,
        const std::string& name, float lo = 0.f,
        float hi = std::numeric_limits<float>::max());

    /// Build from explicit per-voxel arrays (no validation).
    /// An index of subset() that takes no voxel: its value is zero.
    static constexpr uint32_t kNone = 0xffffffffu;
    /// The values of the voxels @a at (indices into this one, or kNone), in that order, stored
    /// the same way (a uniform value stays uniform).
    Attribute subset(const std::vector<uint32_t>& at) const;
    static Attribute fromGrey(std::vector<float> values);
    static Attribute fromRgb(std::vector<openvdb::Vec3f> values);

private:
    Storage mStorage = Storage::Uniform;
    float mUniform = 0.f;
    std::vector<float> mGrey;
    std::vector<openvdb::Vec3f> mRgb;
};

/// "(i, j, k)" for error messages.
std::string formatCoord(const openvdb::Coord& ijk);

} // namespace vdbrad
