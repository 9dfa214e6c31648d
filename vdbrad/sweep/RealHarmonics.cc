#include "vdbrad/sweep/RealHarmonics.h"

#include "vdbrad/core/Constants.h"

#include <algorithm>
#include <cmath>

namespace vdbrad {

void
realSphericalHarmonics(int order, const openvdb::Vec3d& dir, double* out)
{
    const double len = dir.length();
    const double z = len > 0.0 ? dir.z() / len : 1.0;
    const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = std::atan2(dir.y(), dir.x());
    // Associated Legendre functions P_l^m(z) (no Condon-Shortley phase: any consistent sign
    // convention gives orthonormal harmonics), by the standard recurrences, column by column.
    double pmm = 1.0;
    for (int m = 0; m <= order; ++m) {
        if (m > 0) pmm *= (2 * m - 1) * s;
        double p2 = 0.0, p1 = pmm;   // P_{l-2}^m, P_{l-1}^m
        for (int l = m; l <= order; ++l) {
            double p;
            if (l == m) p = pmm;
            else if (l == m + 1) p = (2 * m + 1) * z * pmm;
            else p = ((2 * l - 1) * z * p1 - (l + m - 1) * p2) / (l - m);
            if (l > m) { p2 = p1; p1 = p; }
            // K_lm = sqrt((2l + 1) / 4pi (l - m)! / (l + m)!).
            double ratio = 1.0;
            for (int k = l - m + 1; k <= l + m; ++k) ratio /= k;
            const double K = std::sqrt((2 * l + 1) / (4.0 * kPi) * ratio);
            if (m == 0) {
                out[l * l + l] = K * p;
            } else {
                out[l * l + l + m] = std::sqrt(2.0) * K * p * std::cos(m * phi);
                out[l * l + l - m] = std::sqrt(2.0) * K * p * std::sin(m * phi);
            }
        }
    }
}

} // namespace vdbrad
