#include "vdbrad/glossy/ControlBrdf.h"
#include "vdbrad/core/Constants.h"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace vdbrad {

namespace {
using openvdb::math::Vec3d;
} // namespace

ControlBrdf::ControlBrdf(const ControlPoints& points, const Brdf& brdf, FitNorm norm, int cuts)
    : mPoints(&points), mBrdf(brdf)
{
    const auto t0 = std::chrono::steady_clock::now();
    const size_t P = points.size();
    std::vector<ControlPoints::Sample> samples;
    for (const ControlPoints::Sample& s : points.quadrature(cuts)) {
        if (s.direction.z() > 0.0) samples.push_back(s);
    }
    // Light from a point below the horizon is light from just above it (see the file comment).
    const double lift = std::sin(2.0 * kPi / 180.0);
    std::vector<double> K(P * P, 0.0);
    double sumSq = 0.0;
    size_t counted = 0;
    for (size_t i = 0; i < P; ++i) {
        Vec3d wi = points.point(i);
        const bool above = wi.z() > 0.0;
        // Light arrives from above the horizon: it lands on points at most one triangle
        // below it. Columns further down stay empty, which keeps the support (and the cost of
        // a reflection, ~support^2) to about half of the points.
        if (wi.z() < -std::sin(points.spacing())) continue;
        if (wi.z() < lift) {
            const double h = std::sqrt(wi.x() * wi.x() + wi.y() * wi.y());
            if (h == 0.0) continue;   // the nadir: no light comes from straight below
            const double c = std::sqrt(1.0 - lift * lift) / h;
            wi = Vec3d(wi.x() * c, wi.y() * c, lift);
        }
        FitProblem problem;
        problem.columns = P;
        double peak = 0.0;
        for (const ControlPoints::Sample& s : samples) {
            const double y = kPi * brdf.value(wi, s.direction);
            peak = std::max(peak, y);
            problem.addRow(s.weights.index.data(), s.weights.weight.data(), 3, y, s.solidAngle);
        }
        if (!(peak > 0.0)) continue;
        FitOptions options;
        options.norm = norm;
        // Points no sample touches (well below the horizon) are pulled to 0.
        options.ridge = 1e-12;
        const FitResult fit = fitControlValues(problem, options);
        for (size_t o = 0; o < P; ++o) K[o * P + i] = std::max(fit.x[o], 0.0);
        if (above) {
            mMaxError = std::max(mMaxError, fit.maxAbsolute / peak);
            sumSq += (fit.rms / peak) * (fit.rms / peak);
            ++counted;
        }
    }
    mRmsError = counted ? std::sqrt(sumSq / double(counted)) : 0.0;

    mKernel.assign(P * P, 0.f);
    std::vector<char> used(P, 0);
    for (size_t o = 0; o < P; ++o) {
        for (size_t i = 0; i < P; ++i) {
            const double k = 0.5 * (K[o * P + i] + K[i * P + o]);
            mKernel[o * P + i] = float(k);
            if (k != 0.0) used[o] = used[i] = 1;
        }
    }
    for (size_t o = 0; o < P; ++o) {
        if (used[o]) mSupport.push_back(uint32_t(o));
    }
    const size_t s = mSupport.size();
    std::vector<double> compact(s * s);
    for (size_t o = 0; o < s; ++o) {
        for (size_t i = 0; i < s; ++i) {
            compact[o * s + i] = double(mKernel[size_t(mSupport[o]) * P + mSupport[i]]);
        }
    }
    mCompact.assign(s, std::move(compact));
    mSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double
ControlBrdf::value(const Vec3d& wi, const Vec3d& wo) const
{
    const ControlPoints::Weights a = mPoints->weights(wi), b = mPoints->weights(wo);
    const size_t P = size();
    double v = 0.0;
    for (int p = 0; p < 3; ++p) {
        for (int q = 0; q < 3; ++q) {
            v += b.weight[size_t(p)] * a.weight[size_t(q)]
                * double(mKernel[size_t(b.index[size_t(p)]) * P + a.index[size_t(q)]]);
        }
    }
    return v;
}

} // namespace vdbrad
