// Scene-loading benchmark: how much buildScene and whole-file I/O cost next to OpenVDB doing the
// nearest equivalent work in the same process (ratios, not absolute times, are the result).
//
//   build/benchmarks/bench_scene [resolution ...]      (default 256 512)
#include "BenchTiming.h"
#include "grids/CanonicalGrids.h"
#include "vdbrad/vdbrad.h"

#include <openvdb/io/File.h>
#include <openvdb/tools/GridOperators.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <unistd.h>

namespace {

using vdbrad::bench::timeIt;

void
row(const char* what, int res, size_t voxels, double ours, double base, const char* baseline)
{
    std::printf("%-34s %5d %11zu %9.3f %9.3f %7.2fx  (baseline: %s)\n", what, res, voxels, ours,
        base, ours / base, baseline);
}

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    std::vector<int> resolutions;
    for (int i = 1; i < argc; ++i) resolutions.push_back(std::atoi(argv[i]));
    if (resolutions.empty()) resolutions = {256, 512};
    std::printf("%-34s %5s %11s %9s %9s %8s\n", "case", "res", "voxels", "ours s", "base s",
        "ratio");
    for (int res : resolutions) {
        // Level set: extraction + gradient normals vs OpenVDB's gradient over the narrow band.
        auto ls = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(res) / 2.f,
            openvdb::Vec3f(0.f), 1.f);
        size_t n = 0;
        const double ours = timeIt([&] { n = vdbrad::buildScene({ls}).size(); });
        const double base = timeIt([&] { openvdb::tools::gradient(*ls); });
        row("buildScene(level-set sphere)", res, n, ours, base, "tools::gradient(level set)");

        // Explicit normal grid (Cornell box): vs a deep copy of the three input grids.
        vdbrad::grids::BuildParams p;
        p.res = res;
        const openvdb::GridPtrVec cornell = vdbrad::grids::makeCornell(p);
        const double oursC = timeIt([&] { n = vdbrad::buildScene(cornell).size(); });
        const double baseC = timeIt([&] {
            for (const auto& g : cornell) g->deepCopyGrid();
        });
        row("buildScene(cornell normal grid)", res, n, oursC, baseC, "deepCopy of its 3 grids");

        // Whole-file read from disk: ours (read all, check, parse from memory) vs io::File with
        // delayed loading off.
        vdbrad::VdbFile file;
        file.grids = cornell;
        char name[] = "/tmp/vdbrad_bench_XXXXXX";
        const int fd = ::mkstemp(name);
        ::close(fd);
        vdbrad::writeVdbFile(file, name);
        const double oursR = timeIt([&] { vdbrad::readVdbFile(name); });
        const double baseR = timeIt([&] {
            openvdb::io::File f(name);
            f.open(false);
            f.getGrids();
            f.close();
        });
        row("readVdbFile(cornell)", res, n, oursR, baseR, "io::File open(false)+getGrids");
        const double oursW = timeIt([&] { vdbrad::writeVdbFile(file, name); });
        const double baseW = timeIt([&] { openvdb::io::File(name).write(cornell); });
        row("writeVdbFile(cornell), atomic", res, n, oursW, baseW, "io::File::write");
        ::unlink(name);
    }
    return 0;
}
