#include "vdbrad/VoxelStep.h"

#include "vdbrad/Denormals.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace vdbrad {

std::vector<double>
meanEscapeFactors(const std::vector<float>& kappa, const DirectionSet& directions,
    const std::vector<double>& weight)
{
    const size_t dirs = directions.size();
    std::vector<float> step(dirs);
    for (size_t d = 0; d < dirs; ++d) step[d] = stepLength(directions.direction(d));
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
