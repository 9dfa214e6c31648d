// Direction-set benchmark: DirectionSet::fromRadius(R), which reads the set off the boundary shell
// of the digital ball (O(R²), DirectionSet.cc), against the brute-force scan of the whole cube
// [-R, R]³ for its exposed voxels (O(R³), what tests/test_directions.cc uses as its reference) in
// the same process. The baseline only finds the exposed voxels; fromRadius also computes every
// solid angle and sorts the set, so the ratio understates the gap. "growth" is the time over the
// time at the previous radius: ~4 when R doubles for O(R²) work, ~8 for O(R³).
//
//   build/benchmarks/bench_directions [radius ...]      (default 25 50 100 200 400)
#include "BenchTiming.h"
#include "vdbrad/sweep/DirectionSet.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <vector>

namespace {

using vdbrad::bench::timeIt;

// Exposed voxels of B_R (|p|² <= R² with a face neighbour outside), by scanning the cube.
size_t
scanExposed(int radius)
{
    const int64_t r2 = int64_t(radius) * radius;
    size_t n = 0;
    for (int x = -radius; x <= radius; ++x) {
        for (int y = -radius; y <= radius; ++y) {
            for (int z = -radius; z <= radius; ++z) {
                const int64_t d = int64_t(x) * x + int64_t(y) * y + int64_t(z) * z;
                if (d > r2) continue;
                const int m = std::max({std::abs(x), std::abs(y), std::abs(z)});
                n += d + 2 * m + 1 > r2;   // the face neighbour along the largest |p_k| leaves
            }
        }
    }
    return n;
}

} // namespace

int
main(int argc, char** argv)
{
    std::vector<int> radii;
    for (int i = 1; i < argc; ++i) radii.push_back(std::atoi(argv[i]));
    if (radii.empty()) radii = {25, 50, 100, 200, 400};
    std::printf("%6s %9s %12s %12s %8s %8s  (baseline: scan of [-R, R]^3 for exposed voxels)\n",
        "R", "pairs", "ours ms", "base ms", "ratio", "growth");
    double previous = 0.0;
    for (int r : radii) {
        size_t pairs = 0, exposed = 0;
        const double ours = timeIt([&] { pairs = vdbrad::DirectionSet::fromRadius(r).size(); });
        const double base = timeIt([&] { exposed = scanExposed(r); });
        if (exposed != 2 * pairs) {
            std::fprintf(stderr, "R = %d: %zu exposed voxels for %zu pairs\n", r, exposed, pairs);
            return 1;
        }
        std::printf("%6d %9zu %12.3f %12.3f %7.3fx", r, pairs, ours * 1e3, base * 1e3,
            ours / base);
        if (previous > 0.0) std::printf(" %7.2fx", ours / previous);
        std::printf("\n");
        previous = ours;
    }
    return 0;
}
