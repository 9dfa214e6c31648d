// Canonical-scene benchmark: how long each builder of grids/CanonicalGrids.h (`vdbrad make NAME`)
// takes next to a deep copy of the grids it returns, in the same process: the cost of touching
// its output once (ratios, not absolute times, are the result). Then what reading a simulator's
// double-precision fog costs: the cumulus' density as a DoubleGrid converted to float
// (vdbrad::singlePrecision, what the contract does on read) against a deep copy of that double
// grid and against building the cloud from the float grid.
//
//   build/benchmarks/bench_grids [resolution ...] [-- name ...]   (default 256 512, every scene)
#include "BenchTiming.h"
#include "grids/CanonicalGrids.h"
#include "vdbrad/core/GridContract.h"
#include "vdbrad/scene/Cloud.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

namespace {

using vdbrad::bench::timeIt;

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    std::vector<int> resolutions;
    std::vector<std::string> names;
    bool readingNames = false;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--") == 0) readingNames = true;
        else if (readingNames) names.push_back(argv[i]);
        else resolutions.push_back(std::atoi(argv[i]));
    }
    if (resolutions.empty()) resolutions = {256, 512};
    if (names.empty()) {
        for (const auto& b : vdbrad::grids::builders()) names.push_back(b.name);
    }
    std::printf("%-16s %5s %11s %9s %9s %8s  (baseline: deep copy of the grids it returns)\n",
        "scene", "res", "voxels", "ours s", "base s", "ratio");
    for (const std::string& name : names) {
        const vdbrad::grids::Builder* builder = vdbrad::grids::findBuilder(name);
        if (!builder) {
            std::fprintf(stderr, "no scene called '%s'\n", name.c_str());
            return 1;
        }
        for (int res : resolutions) {
            vdbrad::grids::BuildParams p;
            p.res = res;
            openvdb::GridPtrVec grids;
            const double ours = timeIt([&] { grids = builder->build(p); });
            const double base = timeIt([&] {
                for (const auto& g : grids) g->deepCopyGrid();
            });
            size_t voxels = 0;
            for (const auto& g : grids) voxels = std::max<size_t>(voxels, g->activeVoxelCount());
            std::printf("%-16s %5d %11zu %9.3f %9.3f %7.2fx\n", name.c_str(), res, voxels, ours,
                base, ours / base);
        }
    }

    std::printf("\n%-16s %5s %11s %9s %9s %8s %9s %8s\n", "double density", "res", "voxels",
        "convert s", "copy s", "ratio", "cloud s", "ratio");
    for (int res : resolutions) {
        vdbrad::grids::BuildParams p;
        p.res = res;
        const openvdb::GridPtrVec grids = vdbrad::grids::findBuilder("cumulus")->build(p);
        const auto density = openvdb::gridConstPtrCast<openvdb::FloatGrid>(
            vdbrad::findGrid(grids, "density"));
        auto twice = openvdb::DoubleGrid::create(
            std::make_shared<openvdb::DoubleTree>(density->tree()));
        twice->setName("density");
        twice->setTransform(density->transform().copy());
        openvdb::GridBase::ConstPtr converted;
        const double ours = timeIt([&] { converted = vdbrad::singlePrecision(twice); });
        const double copy = timeIt([&] { twice->deepCopyGrid(); });
        const double cloud = timeIt([&] { vdbrad::buildCloud({density->deepCopy()}); });
        std::printf("%-16s %5d %11zu %9.3f %9.3f %7.2fx %9.3f %7.2fx\n", "cumulus", res,
            size_t(density->activeVoxelCount()), ours, copy, ours / copy, cloud, ours / cloud);
    }
    return 0;
}
