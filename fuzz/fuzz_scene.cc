// libFuzzer target: grids decoded from the fuzzer's bytes (not parsed by OpenVDB's reader) through
// Load.h: the scene contract, the Scene and the Cloud, a tiny solve, render and write.
//
// fuzz_load.cc reaches the same code through the `.vdb` reader, but its crash guard forks on
// every input; here each input is a handful of small grids built in memory, so this target runs
// thousands of inputs per second over what vdbrad itself does with grids: any grid names and
// types, grid classes, transforms (tiny, huge, NaN, non-uniform, offset), coordinates up to
// +-2^30, NaN/Inf/negative values, active tiles, and mixtures of surface and cloud grids.
//
// Run by scripts/fuzz.sh; by hand: VDBRAD_FUZZ_SEEDS=DIR build-hardening/fuzz/fuzz_scene DIR.
#include "Load.h"
#include "Seeds.h"

#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace {

constexpr const char* kNames[] = {"normal", "albedo", "emission", "density", "surface",
    "radiosity", "temperature", ""};

float
value(FuzzedDataProvider& in)
{
    switch (in.ConsumeIntegralInRange<int>(0, 7)) {
    case 0: return std::numeric_limits<float>::quiet_NaN();
    case 1: return std::numeric_limits<float>::infinity();
    case 2: return -1.f;
    case 3: return 0.f;
    case 4: return 1.f;
    default: return in.ConsumeFloatingPoint<float>();
    }
}

double
voxelSize(FuzzedDataProvider& in)
{
    switch (in.ConsumeIntegralInRange<int>(0, 6)) {
    case 0: return 1e-30;
    case 1: return 1e30;
    case 2: return -0.1;
    case 3: return std::numeric_limits<double>::quiet_NaN();
    case 4: return in.ConsumeFloatingPoint<double>();
    default: return 0.1;
    }
}

openvdb::Coord
coord(FuzzedDataProvider& in, const openvdb::Coord& origin)
{
    // Within 16 voxels of the grid's origin, so that voxels meet and a grid has one top-level
    // node (each costs OpenVDB a 300 KB table: the fuzzer's speed); the origin may be anywhere.
    return origin.offsetBy(in.ConsumeIntegralInRange<int>(0, 15),
        in.ConsumeIntegralInRange<int>(0, 15), in.ConsumeIntegralInRange<int>(0, 15));
}

template<typename GridT, typename MakeValue>
openvdb::GridBase::Ptr
fill(FuzzedDataProvider& in, const openvdb::Coord& origin, MakeValue&& make)
{
    auto grid = GridT::create();
    const int voxels = in.ConsumeIntegralInRange<int>(0, 48);
    for (int i = 0; i < voxels && in.remaining_bytes() > 0; ++i) {
        grid->tree().setValueOn(coord(in, origin), make());
    }
    // An active tile: a dense 8^3 block, or rarely a 4096^3 root tile (a few bytes in a file)
    // that every reader must refuse before densifying it. (128^3 tiles, 2 M real voxels, only
    // made the fuzzer slow.)
    if (in.ConsumeIntegralInRange<int>(0, 15) == 0) {
        const int level = in.ConsumeIntegralInRange<int>(0, 15) == 0 ? 3 : 1;
        grid->tree().addTile(level, coord(in, origin), make(), true);
    }
    return grid;
}

openvdb::GridBase::Ptr
makeGrid(FuzzedDataProvider& in, const openvdb::Coord& origin, openvdb::math::Transform::Ptr xf)
{
    openvdb::GridBase::Ptr grid;
    auto scalar = [&] { return value(in); };
    auto vector = [&] { return openvdb::Vec3f(value(in), value(in), value(in)); };
    switch (in.ConsumeIntegralInRange<int>(0, 4)) {
    case 0: grid = fill<openvdb::FloatGrid>(in, origin, scalar); break;
    case 1: grid = fill<openvdb::Vec3SGrid>(in, origin, vector); break;
    case 2: grid = fill<openvdb::DoubleGrid>(in, origin, [&] { return double(value(in)); }); break;
    case 3: grid = fill<openvdb::Int32Grid>(in, origin, [&] { return in.ConsumeIntegral<int>(); });
        break;
    default: grid = fill<openvdb::BoolGrid>(in, origin, [&] { return in.ConsumeBool(); }); break;
    }
    grid->setName(in.PickValueInArray(kNames));
    grid->setGridClass(in.PickValueInArray(
        {openvdb::GRID_UNKNOWN, openvdb::GRID_LEVEL_SET, openvdb::GRID_FOG_VOLUME}));
    // Usually the file's shared transform; sometimes a grid of its own (mismatch, non-cubic).
    if (in.ConsumeIntegralInRange<int>(0, 7) == 0) {
        xf = openvdb::math::Transform::createLinearTransform(voxelSize(in));
        if (in.ConsumeBool()) xf->preScale(openvdb::Vec3d(1.0, 2.0, 1.0));
    }
    grid->setTransform(xf);
    return grid;
}

vdbrad::VdbFile
decode(FuzzedDataProvider& in)
{
    vdbrad::VdbFile file;
    // At 0, or anywhere up to +-2^30 (rounded to 16 so that the grids' 16^3 stays in one node).
    const int far = 1 << 26;
    auto farAxis = [&] { return 16 * in.ConsumeIntegralInRange<int>(-far, far - 1); };
    const openvdb::Coord origin = in.ConsumeBool() ? openvdb::Coord(0)
        : openvdb::Coord(farAxis(), farAxis(), farAxis());
    auto xf = openvdb::math::Transform::createLinearTransform(voxelSize(in));
    if (in.ConsumeBool()) xf->postTranslate(openvdb::Vec3d(0.05, -3.0, 1e6));
    const int count = in.ConsumeIntegralInRange<int>(1, 4);
    for (int i = 0; i < count; ++i) file.grids.push_back(makeGrid(in, origin, xf));
    return file;
}

// Seeds: patterned byte strings. decode() accepts any bytes (FuzzedDataProvider), so seeds only
// need variety; coverage feedback finds valid scenes (e.g. normals made of 0 and 1 entries) fast.
std::vector<std::string>
seeds()
{
    std::vector<std::string> out;
    for (int k = 0; k < 8; ++k) {
        std::string s(512, '\0');
        for (size_t i = 0; i < s.size(); ++i) s[i] = char((i * 131 + size_t(k) * 17) & 0xff);
        out.push_back(s);
    }
    return out;
}

} // namespace

extern "C" int
LLVMFuzzerInitialize(int*, char***)
{
    openvdb::initialize();
    vdbrad::fuzz::writeSeeds(seeds());
    return 0;
}

extern "C" int
LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    FuzzedDataProvider in(data, size);
    try {
        vdbrad::fuzz::useFile(decode(in));
    } catch (const openvdb::Exception&) {
    } catch (const std::bad_alloc&) {
    }
    return 0;
}
