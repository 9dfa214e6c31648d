// Crash-guard benchmark (vdbrad/core/GridIO.h): what parsing untrusted bytes in a forked child first
// costs, and how long the guard waits for a child that hangs, each against a baseline run in the
// same process (ratios, not absolute times, are the result).
//
//   parseVdb (guard: a child parses and reads every leaf, then the parent parses), the child's
//   parse alone and the fork alone (a child with no work), against one plain parse of the same
//   bytes by openvdb::io::Stream without delayed loading (what the parent does), on
//   `vdbrad make cornell` files;
//   runGuarded on work that never returns, with a wall-clock limit of W seconds (tried twice,
//   then the child is killed), against sleeping 2 W: the ratio should stay near 1.
//
//   build/benchmarks/bench_guard [resolution ...]      (default 128 256)
#include "BenchTiming.h"
#include "grids/CanonicalGrids.h"
#include "vdbrad/core/CrashGuard.h"
#include "vdbrad/core/GridIO.h"

#include <openvdb/io/Stream.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <sstream>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

using vdbrad::bench::timeIt;

void
row(const char* what, const char* size, double ours, double base, const char* baseline)
{
    std::printf("%-30s %12s %9.3f %9.3f %7.2fx  (baseline: %s)\n", what, size, ours, base,
        ours / base, baseline);
}

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    std::vector<int> resolutions;
    for (int i = 1; i < argc; ++i) resolutions.push_back(std::atoi(argv[i]));
    if (resolutions.empty()) resolutions = {128, 256};
    std::printf("%-30s %12s %9s %9s %8s\n", "case", "size", "ours s", "base s", "ratio");
    for (int res : resolutions) {
        vdbrad::grids::BuildParams p;
        p.res = res;
        vdbrad::VdbFile file;
        file.grids = vdbrad::grids::makeCornell(p);
        const std::string bytes = vdbrad::serializeVdb(file);
        auto plainParse = [&bytes] {
            std::istringstream in(bytes);
            openvdb::io::Stream(in, /*delayLoad=*/false).getGrids();
        };
        const double base = timeIt(plainParse);
        const double guarded = timeIt([&] { vdbrad::parseVdb(bytes); });
        const double child = timeIt([&] { vdbrad::runGuarded(plainParse, bytes.size()); });
        const double fork = timeIt([&] { vdbrad::runGuarded([] {}, bytes.size()); });
        char size[32];
        std::snprintf(size, sizeof(size), "%.1f MB", bytes.size() / 1e6);
        const char* baseline = "io::Stream parse of the same bytes, in this process";
        std::printf("cornell %d:\n", res);
        row("  parseVdb", size, guarded, base, baseline);
        row("  runGuarded(io::Stream parse)", size, child, base, baseline);
        row("  runGuarded(no work)", size, fork, base, baseline);
    }
    // A child that hangs: the guard gives up after W seconds, tries once more, then kills it.
    const unsigned wall = 1;
    const double ours = timeIt([&] {
        try {
            vdbrad::runGuarded([] { for (;;) ::pause(); }, 0, wall);
        } catch (const openvdb::IoError&) {
        }
    }, 1);
    const double base =
        timeIt([&] { std::this_thread::sleep_for(std::chrono::seconds(2 * wall)); }, 1);
    row("runGuarded(hang), W = 1 s", "-", ours, base, "sleeping 2 W");
    return 0;
}
