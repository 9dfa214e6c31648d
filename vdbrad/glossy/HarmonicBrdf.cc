#include "vdbrad/glossy/HarmonicBrdf.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/glossy/ControlPoints.h"

#include <Eigen/Core>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>

namespace vdbrad {

namespace {
// Lobe samples per incident direction (a side of the stratified grid).
constexpr int kStrata = 16;
using openvdb::math::Vec3d;
} // namespace

HarmonicBrdf::HarmonicBrdf(const SphericalHarmonics& harmonics, const Brdf& brdf)
    : mHarmonics(&harmonics), mBrdf(brdf)
{
    const auto t0 = std::chrono::steady_clock::now();
    const size_t N = harmonics.size();
    // The outer integral: 642 points' triangles cut in 4, upper half (~2,600 directions, ~2.2
    // degrees apart: the inner integral is smooth in w_i, but for the horizon's cut).
    std::vector<ControlPoints::Sample> outer;
    for (const ControlPoints::Sample& s : ControlPoints(3).quadrature(2)) {
        if (s.direction.z() > 0.0) outer.push_back(s);
    }
    // Row j of M: Y(w_i) solid angle, and of T: int pi lobe(w_i, w_o) Y(w_o) dw_o.
    std::vector<double> M(outer.size() * N), T(outer.size() * N, 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, outer.size()),
        [&](const tbb::blocked_range<size_t>& r) {
            std::vector<double> y(N);
            for (size_t j = r.begin(); j != r.end(); ++j) {
                const Vec3d& wi = outer[j].direction;
                harmonics.basis(wi, &M[j * N]);
                for (size_t a = 0; a < N; ++a) M[j * N + a] *= outer[j].solidAngle;
                double* t = &T[j * N];
                for (int u = 0; u < kStrata; ++u) {
                    for (int v = 0; v < kStrata; ++v) {
                        double pdf = 0.0;
                        const Vec3d wo = brdf.sample(wi, (u + 0.5) / kStrata,
                            (v + 0.5) / kStrata, pdf);
                        if (!(pdf > 0.0) || wo.z() <= 0.0) continue;
                        const double f = kPi * brdf.value(wi, wo) / pdf;
                        if (f == 0.0) continue;
                        harmonics.basis(wo, y.data());
                        for (size_t a = 0; a < N; ++a) t[a] += f * y[a];
                    }
                }
                for (size_t a = 0; a < N; ++a) t[a] /= double(kStrata * kStrata);
            }
        });
    using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const Eigen::Map<const Matrix> m(M.data(), Eigen::Index(outer.size()), Eigen::Index(N));
    const Eigen::Map<const Matrix> t(T.data(), Eigen::Index(outer.size()), Eigen::Index(N));
    // K_ab = sum_j T_ja M_jb over the upper hemispheres, symmetrised; the even extension
    // doubles it on each side for the harmonics even in z (Y_lm(x, y, -z) = (-1)^(l+m)
    // Y_lm(x, y, z)) and cancels it for the odd ones.
    const Matrix K = t.transpose() * m;
    std::vector<double> parity(N);
    for (int l = 0; l <= harmonics.order(); ++l) {
        for (int mm = -l; mm <= l; ++mm) parity[size_t(l * l + l + mm)] = (l + mm) % 2 ? 0.0 : 2.0;
    }
    std::vector<double> kernel(N * N);
    for (size_t a = 0; a < N; ++a) {
        for (size_t b = 0; b < N; ++b) {
            kernel[a * N + b] = parity[a] * parity[b] * 0.5 * (K(Eigen::Index(a), Eigen::Index(b))
                + K(Eigen::Index(b), Eigen::Index(a)));
        }
    }
    mKernel.assign(N, std::move(kernel));
    mSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double
HarmonicBrdf::value(const Vec3d& wi, const Vec3d& wo) const
{
    const size_t N = size();
    std::vector<double> a(N), b(N);
    mHarmonics->basis(wo, a.data());
    mHarmonics->basis(wi, b.data());
    double v = 0.0;
    for (size_t p = 0; p < N; ++p) {
        double row = 0.0;
        for (size_t q = 0; q < N; ++q) row += mKernel.wide()[p * N + q] * b[q];
        v += a[p] * row;
    }
    return v;
}

} // namespace vdbrad
