#include "vdbrad/cloud/HarmonicQuadrature.h"

#include "vdbrad/cloud/PhaseFunction.h"
#include "vdbrad/core/Constants.h"
#include "vdbrad/sweep/RealHarmonics.h"

#include <algorithm>
#include <cmath>

namespace vdbrad {

namespace {


/// The fit at even degree @a degree; empty factors if a weight would fall below a quarter of
/// its cell.
HarmonicQuadrature
fitAt(const DirectionSet& directions, int degree, const std::vector<double>& harmonics)
{
    const size_t n = directions.size(), M = size_t(degree + 1) * size_t(degree + 1);
    // Constraint rows scaled by sqrt(W) (x = (A' - A) / sqrt(A)), with the right-hand side
    // b - C A in the last column, so that row operations carry it along.
    std::vector<std::vector<double>> rows;
    for (int l = 0; l <= degree; l += 2) {
        for (int m = -l; m <= l; ++m) {
            const size_t lm = size_t(l * l + l + m);
            std::vector<double> row(n + 1);
            double exact = l == 0 ? 2.0 / std::sqrt(4.0 * kPi) : 0.0, sum = 0.0;
            for (size_t k = 0; k < n; ++k) {
                const double y = harmonics[k * M + lm], a = directions.factor(k);
                row[k] = y * std::sqrt(a);
                sum += a * y;
            }
            row[n] = exact - sum;
            rows.push_back(std::move(row));
        }
    }
    // Modified Gram-Schmidt, twice per row for orthogonality; a row left with under 1e-9 of its
    // norm is a combination of earlier ones (its right-hand side then is too: the exact
    // integrals are consistent) and is dropped.
    std::vector<std::vector<double>> basis;
    for (auto& row : rows) {
        double norm0 = 0.0;
        for (size_t k = 0; k < n; ++k) norm0 += row[k] * row[k];
        for (int pass = 0; pass < 2; ++pass) {
            for (const auto& q : basis) {
                double dot = 0.0;
                for (size_t k = 0; k < n; ++k) dot += q[k] * row[k];
                for (size_t k = 0; k <= n; ++k) row[k] -= dot * q[k];
            }
        }
        double norm = 0.0;
        for (size_t k = 0; k < n; ++k) norm += row[k] * row[k];
        if (!(norm > 1e-18 * norm0)) continue;
        const double inv = 1.0 / std::sqrt(norm);
        for (double& v : row) v *= inv;
        basis.push_back(std::move(row));
    }
    HarmonicQuadrature q;
    q.degree = degree;
    q.factors.resize(n);
    for (size_t k = 0; k < n; ++k) {
        double x = 0.0;
        for (const auto& b : basis) x += b[n] * b[k];
        const double a = directions.factor(k);
        q.factors[k] = a + std::sqrt(a) * x;
        if (!(q.factors[k] > 0.25 * a)) return HarmonicQuadrature();
    }
    for (int l = 0; l <= degree; l += 2) {
        for (int m = -l; m <= l; ++m) {
            const size_t lm = size_t(l * l + l + m);
            double sum = 0.0;
            for (size_t k = 0; k < n; ++k) sum += q.factors[k] * harmonics[k * M + lm];
            const double exact = l == 0 ? 2.0 / std::sqrt(4.0 * kPi) : 0.0;
            q.residual = std::max(q.residual, std::abs(sum - exact));
        }
    }
    return q;
}

} // namespace

HarmonicQuadrature
fitHarmonicQuadrature(const DirectionSet& directions, int degree)
{
    const size_t n = directions.size();
    degree -= degree % 2;
    // Never more constraints than weights: sum over even l <= D of 2l + 1 = (D + 1)(D + 2) / 2.
    while (degree > 0 && size_t(degree + 1) * size_t(degree + 2) / 2 > n) degree -= 2;
    const size_t M = size_t(degree + 1) * size_t(degree + 1);
    std::vector<double> harmonics(n * M);
    for (size_t k = 0; k < n; ++k) {
        realSphericalHarmonics(degree, directions.unit(k), &harmonics[k * M]);
    }
    for (; degree > 0; degree -= 2) {
        // Harmonics of the lower degree are a prefix of each direction's row: re-pack them.
        const size_t m = size_t(degree + 1) * size_t(degree + 1);
        std::vector<double> packed(n * m);
        for (size_t k = 0; k < n; ++k) {
            std::copy_n(&harmonics[k * M], m, &packed[k * m]);
        }
        HarmonicQuadrature q = fitAt(directions, degree, packed);
        if (!q.factors.empty()) return q;
    }
    HarmonicQuadrature q;
    q.factors.resize(n);
    for (size_t k = 0; k < n; ++k) q.factors[k] = directions.factor(k);
    return q;
}

} // namespace vdbrad
