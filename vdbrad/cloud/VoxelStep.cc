#include "vdbrad/cloud/VoxelStep.h"

#include "vdbrad/core/Denormals.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <numeric>

namespace vdbrad {

SweptLine
sweptLine(const openvdb::Coord& sigma, const FlatAxes& flat)
{
    SweptLine out;
    openvdb::Coord s = sigma;
    int g = 0, longest = 0;
    for (int k = 0; k < 3; ++k) {
        if (flat[k]) s[k] = 0;
        g = std::gcd(g, std::abs(s[k]));
        longest = std::max(longest, std::abs(s[k]));
    }
    if (g == 0) {
        out.isolated = true;
        out.step = kIsolatedStep;
        int k = 0;
        while (k < 2 && flat[k]) ++k;
        out.sigma = openvdb::Coord(0);
        out.sigma[k] = 1;
        out.unit = out.sigma.asVec3d();
        return out;
    }
    // (sigma itself where nothing was zeroed: bit for bit the direction set's line and unit.)
    if (s != sigma) s = openvdb::Coord(s.x() / g, s.y() / g, s.z() / g);
    out.sigma = s;
    out.unit = out.sigma.asVec3d().unit();
    // The swept line advances one voxel per step along its major axis, and sigma moves
    // |sigma| / |sigma_major| voxels in 3D for each.
    out.step = float(sigma.asVec3d().length() / double(longest));
    return out;
}

std::vector<double>
meanEscapeFactors(const std::vector<float>& kappa, const std::vector<float>& step,
    const std::vector<double>& weight)
{
    const size_t dirs = step.size();
    std::vector<double> escape(kappa.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, kappa.size()),
        [&](const tbb::blocked_range<size_t>& r) {
            const ScopedFlushDenormals flush;   // as in the sweeps
            float last = -1.f;
            double sum = 0.0;
            for (size_t i = r.begin(); i != r.end(); ++i) {
                if (kappa[i] != last) {
                    last = kappa[i];
                    sum = 0.0;
                    for (size_t d = 0; d < dirs; ++d) {
                        float absorb, mean;
                        stepFactors(last * step[d], absorb, mean);
                        sum += weight[d] * double(mean);
                    }
                }
                escape[i] = sum;
            }
        });
    return escape;
}

} // namespace vdbrad
