#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/core/Constants.h"

#include <openvdb/Exceptions.h>

#include <algorithm>
#include <cmath>

namespace vdbrad {

namespace {
using openvdb::math::Vec3d;

// Smith's Lambda for GGX at a direction of cosine c to the normal.
double
lambda(double alpha, double c)
{
    const double c2 = c * c;
    const double tan2 = std::max(0.0, 1.0 - c2) / std::max(c2, 1e-300);
    return 0.5 * (std::sqrt(1.0 + alpha * alpha * tan2) - 1.0);
}
} // namespace

const char*
brdfModelName(BrdfModel model)
{
    switch (model) {
        case BrdfModel::Phong: return "phong";
        case BrdfModel::BlinnPhong: return "blinn-phong";
        case BrdfModel::Ggx: break;
    }
    return "ggx";
}

BrdfModel
brdfModelFromName(const std::string& name)
{
    if (name == "phong") return BrdfModel::Phong;
    if (name == "blinn-phong") return BrdfModel::BlinnPhong;
    if (name == "ggx") return BrdfModel::Ggx;
    OPENVDB_THROW(openvdb::ValueError, "unknown BRDF '" << name
        << "' (phong, blinn-phong or ggx)");
}

Brdf::Brdf(BrdfModel model, double roughness) : mModel(model), mRoughness(roughness)
{
    if (!(roughness >= kMinRoughness && roughness <= 1.0)) {
        OPENVDB_THROW(openvdb::ValueError, "roughness must be in [" << kMinRoughness
            << ", 1], got " << roughness);
    }
    mAlpha = roughness * roughness;
    mExponent = 2.0 / (mAlpha * mAlpha) - 2.0;
    const double N = mExponent;
    switch (model) {
        case BrdfModel::Phong: mNorm = (N + 2.0) / (2.0 * kPi); break;
        case BrdfModel::BlinnPhong:
            mNorm = (N + 2.0) * (N + 4.0) / (8.0 * kPi * (std::pow(2.0, -0.5 * N) + N));
            break;
        case BrdfModel::Ggx: mNorm = 1.0; break;
    }
    // The transfer T_io between bands of cos(theta): from incidence at band i's centre, the
    // raw lobe's reflected share landing in band o, by stratified importance sampling; over
    // the band's measure mu d(mu) it is symmetric (reciprocity), so it is symmetrised and d
    // solves d_i sum_o S_io d_o m_o = 1 (m_o = mu_o / M the band's measure).
    const int M = kBands, strata = 64;
    std::vector<double> S(size_t(M) * M, 0.0), m(static_cast<size_t>(M));
    for (int i = 0; i < M; ++i) {
        const double mu = (i + 0.5) / M;
        m[size_t(i)] = mu / M;
        const Vec3d wi(std::sqrt(1.0 - mu * mu), 0.0, mu);
        for (int a = 0; a < strata; ++a) {
            for (int b = 0; b < strata; ++b) {
                double pdf = 0.0;
                const Vec3d wo = sample(wi, (a + 0.5) / strata, (b + 0.5) / strata, pdf);
                if (wo.z() <= 0.0 || !(pdf > 0.0)) continue;
                const int o = std::min(M - 1, int(wo.z() * M));
                S[size_t(i) * M + size_t(o)] += rawValue(wi, wo) * wo.z() / pdf;
            }
        }
    }
    for (int i = 0; i < M; ++i) {
        for (int o = 0; o < M; ++o) S[size_t(i) * M + size_t(o)] /= double(strata * strata)
            * m[size_t(o)];
    }
    for (int i = 0; i < M; ++i) {
        for (int o = i + 1; o < M; ++o) {
            const double v = 0.5 * (S[size_t(i) * M + size_t(o)] + S[size_t(o) * M + size_t(i)]);
            S[size_t(i) * M + size_t(o)] = S[size_t(o) * M + size_t(i)] = v;
        }
    }
    std::vector<double>& d = mCompensation;
    d.assign(size_t(M), 1.0);
    for (int it = 0; it < 2000; ++it) {
        double worst = 0.0;
        for (int i = 0; i < M; ++i) {
            double r = 0.0;
            for (int o = 0; o < M; ++o) r += S[size_t(i) * M + size_t(o)] * d[size_t(o)] * m[size_t(o)];
            worst = std::max(worst, std::abs(d[size_t(i)] * r - 1.0));
            if (r > 0.0) d[size_t(i)] = std::sqrt(d[size_t(i)] / r);
        }
        if (worst < 1e-9) break;
    }
}

double
Brdf::compensation(double mu) const
{
    const double x = std::clamp(mu, 0.0, 1.0) * kBands - 0.5;
    const int i = std::clamp(int(std::floor(x)), 0, kBands - 2);
    const double t = std::clamp(x - i, 0.0, 1.0);
    return mCompensation[size_t(i)] * (1.0 - t) + mCompensation[size_t(i) + 1] * t;
}

double
Brdf::value(const Vec3d& wi, const Vec3d& wo) const
{
    if (wi.z() <= 0.0 || wo.z() <= 0.0) return 0.0;
    return compensation(wi.z()) * rawValue(wi, wo) * compensation(wo.z());
}

double
Brdf::roughnessFromExponent(double ns)
{
    // N = 2 / alpha^2 - 2 inverted; alpha = roughness^2.
    const double alpha = std::sqrt(2.0 / (std::max(ns, 0.0) + 2.0));
    return std::clamp(std::sqrt(alpha), kMinRoughness, 1.0);
}

double
Brdf::rawValue(const Vec3d& wi, const Vec3d& wo) const
{
    const double ci = wi.z(), co = wo.z();
    if (ci <= 0.0 || co <= 0.0) return 0.0;
    switch (mModel) {
        case BrdfModel::Phong: {
            const Vec3d r(-wi.x(), -wi.y(), wi.z());   // mirror of wi about z
            const double c = r.dot(wo);
            return c > 0.0 ? mNorm * std::pow(c, mExponent) : 0.0;
        }
        case BrdfModel::BlinnPhong: {
            const Vec3d h = (wi + wo).unit();
            return mNorm * std::pow(std::max(h.z(), 0.0), mExponent);
        }
        case BrdfModel::Ggx: break;
    }
    const Vec3d h = (wi + wo).unit();
    const double a2 = mAlpha * mAlpha, c2 = h.z() * h.z();
    const double d = a2 / (kPi * (c2 * (a2 - 1.0) + 1.0) * (c2 * (a2 - 1.0) + 1.0));
    const double g = 1.0 / (1.0 + lambda(mAlpha, ci) + lambda(mAlpha, co));
    return d * g / (4.0 * ci * co);
}

Vec3d
Brdf::sample(const Vec3d& wo, double u1, double u2, double& pdf) const
{
    // Around an axis: cos(theta) of the axis and the azimuth.
    auto around = [](const Vec3d& axis, double c, double phi) {
        const Vec3d t = std::abs(axis.x()) < 0.6 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
        const Vec3d a = axis.cross(t).unit(), b = axis.cross(a);
        const double s = std::sqrt(std::max(0.0, 1.0 - c * c));
        return (a * (s * std::cos(phi)) + b * (s * std::sin(phi)) + axis * c).unit();
    };
    const double phi = 2.0 * kPi * u2;
    const double N = mExponent;
    if (mModel == BrdfModel::Phong) {
        const Vec3d r(-wo.x(), -wo.y(), wo.z());
        const double c = std::pow(1.0 - u1, 1.0 / (N + 1.0));   // 1 - u1: never 0
        pdf = (N + 1.0) / (2.0 * kPi) * std::pow(c, N);
        return around(r, c, phi);
    }
    Vec3d h;
    double pdfH;
    if (mModel == BrdfModel::BlinnPhong) {
        const double c = std::pow(1.0 - u1, 1.0 / (N + 1.0));
        h = around(Vec3d(0, 0, 1), c, phi);
        pdfH = (N + 1.0) / (2.0 * kPi) * std::pow(c, N);
    } else {
        // GGX: tan^2 theta_h = alpha^2 u / (1 - u), density D(h) cos theta_h.
        const double a2 = mAlpha * mAlpha;
        const double c2 = (1.0 - u1) / (1.0 + (a2 - 1.0) * u1);
        const double c = std::sqrt(std::max(c2, 0.0));
        h = around(Vec3d(0, 0, 1), c, phi);
        const double d = a2 / (kPi * (c2 * (a2 - 1.0) + 1.0) * (c2 * (a2 - 1.0) + 1.0));
        pdfH = d * c;
    }
    const double vh = wo.dot(h);
    pdf = pdfH / (4.0 * std::max(std::abs(vh), 1e-12));
    return h * (2.0 * vh) - wo;
}

double
Brdf::albedo(double cosIncident, int samples, bool raw) const
{
    // Midpoint rule in (cos_o^2, phi): cos_o dw_o = (1/2) d(cos^2) dphi, which takes the
    // cosine out of the integrand; lobes are smooth enough at the roughnesses allowed.
    const Vec3d wi(std::sqrt(std::max(0.0, 1.0 - cosIncident * cosIncident)), 0.0, cosIncident);
    double sum = 0.0;
    for (int a = 0; a < samples; ++a) {
        const double c2 = (a + 0.5) / samples, c = std::sqrt(c2), s = std::sqrt(1.0 - c2);
        for (int b = 0; b < 2 * samples; ++b) {
            const double phi = kPi * (b + 0.5) / samples;
            const Vec3d wo(s * std::cos(phi), s * std::sin(phi), c);
            sum += raw ? rawValue(wi, wo) : value(wi, wo);
        }
    }
    return sum * 0.5 * (1.0 / samples) * (kPi / samples);
}

} // namespace vdbrad
