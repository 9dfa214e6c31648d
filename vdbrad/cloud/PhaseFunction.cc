#include "vdbrad/cloud/PhaseFunction.h"
#include "vdbrad/core/Constants.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/sweep/RealHarmonics.h"

#include <openvdb/Exceptions.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <utility>

namespace vdbrad {

namespace {
constexpr int kMaxOrder = 64;
} // namespace

PhaseFunction
PhaseFunction::henyeyGreenstein(double g)
{
    if (!(g > -1.0 && g < 1.0)) {
        OPENVDB_THROW(openvdb::ValueError, "Henyey-Greenstein g must be in (-1, 1), got " << g);
    }
    PhaseFunction p;
    p.mHg = g != 0.0;
    p.mG = g;
    return p;
}

PhaseFunction
PhaseFunction::legendre(std::vector<double> chi)
{
    if (chi.empty() || chi[0] != 1.0) {
        OPENVDB_THROW(openvdb::ValueError, "Legendre phase coefficients must start with chi_0 = 1");
    }
    for (size_t l = 0; l < chi.size(); ++l) {
        if (!(std::abs(chi[l]) <= 1.0)) {
            OPENVDB_THROW(openvdb::ValueError, "Legendre phase coefficient chi_" << l
                << " must be in [-1, 1], got " << chi[l]);
        }
    }
    while (chi.size() > 1 && chi.back() == 0.0) chi.pop_back();
    PhaseFunction p;
    p.mChi = std::move(chi);
    return p;
}

PhaseFunction
PhaseFunction::readLegendre(const std::string& path)
{
    std::ifstream in(path);
    if (!in) OPENVDB_THROW(openvdb::IoError, "cannot read phase file " << path);
    std::vector<double> chi;
    std::string text;
    for (size_t line = 1; std::getline(in, text); ++line) {
        text = text.substr(0, text.find('#'));
        std::replace(text.begin(), text.end(), ',', ' ');
        std::istringstream words(text);
        for (std::string word; words >> word;) {
            char* end = nullptr;
            const double v = std::strtod(word.c_str(), &end);
            if (*end != '\0' || !std::isfinite(v)) {
                OPENVDB_THROW(openvdb::ValueError, path << " line " << line << ": '" << word
                    << "' is not a number (expected Legendre coefficients chi_0 = 1, chi_1, ...)");
            }
            if (chi.size() == kMaxCoefficients) {
                OPENVDB_THROW(openvdb::ValueError, path << " holds more than "
                    << kMaxCoefficients << " Legendre coefficients");
            }
            chi.push_back(v);
        }
    }
    if (in.bad()) OPENVDB_THROW(openvdb::IoError, "cannot read phase file " << path);
    if (chi.empty()) OPENVDB_THROW(openvdb::ValueError, path << " holds no Legendre coefficients");
    // Tables list beta_l = (2l + 1) chi_l as often as chi_l; beta_1 = 3 g exceeds 1 where g > 1/3.
    bool beta = chi.size() > 1 && std::abs(chi[1]) > 1.0;
    for (size_t l = 0; l < chi.size() && beta; ++l) {
        beta = std::abs(chi[l]) <= 2.0 * double(l) + 1.0;
    }
    if (beta) {
        OPENVDB_THROW(openvdb::ValueError, path << ": chi_1 = " << chi[1] << " > 1: these "
            "look like (2l + 1) chi_l; divide each by 2l + 1");
    }
    try {
        return legendre(std::move(chi));
    } catch (const openvdb::ValueError& e) {
        OPENVDB_THROW(openvdb::ValueError, path << ": " << errorMessage(e));
    }
}

std::string
PhaseFunction::text() const
{
    std::ostringstream os;
    os.precision(17);
    if (mHg) {
        os << "hg " << mG;
    } else if (isIsotropic()) {
        os << "isotropic";
    } else {
        os << "legendre";
        for (const double c : mChi) os << ' ' << c;
    }
    return os.str();
}

PhaseFunction
PhaseFunction::parse(const std::string& text)
{
    std::istringstream in(text);
    std::string kind;
    in >> kind;
    std::vector<double> numbers;
    for (double v; in >> v;) numbers.push_back(v);
    const bool clean = in.eof();
    if (clean && kind == "isotropic" && numbers.empty()) return PhaseFunction();
    if (clean && kind == "hg" && numbers.size() == 1) return henyeyGreenstein(numbers[0]);
    if (clean && kind == "legendre" && !numbers.empty()) return legendre(std::move(numbers));
    OPENVDB_THROW(openvdb::ValueError, "not a phase function: '" << text.substr(0, 60) << "'");
}

double
PhaseFunction::chi(int l) const
{
    if (l < 0) return 0.0;
    if (mHg) return std::pow(mG, l);
    return size_t(l) < mChi.size() ? mChi[size_t(l)] : 0.0;
}

double
PhaseFunction::value(double mu) const
{
    if (mHg) {
        const double g2 = mG * mG;
        return (1.0 - g2) / std::pow(1.0 + g2 - 2.0 * mG * mu, 1.5);
    }
    double sum = 0.0, p0 = 1.0, p1 = mu;
    for (size_t l = 0; l < mChi.size(); ++l) {
        double pl = l == 0 ? 1.0 : mu;
        if (l >= 2) {
            pl = ((2.0 * double(l) - 1.0) * mu * p1 - (double(l) - 1.0) * p0) / double(l);
            p0 = p1;
            p1 = pl;
        }
        sum += (2.0 * double(l) + 1.0) * mChi[l] * pl;
    }
    return sum;
}

PhaseFunction::Truncated
PhaseFunction::truncate(int order) const
{
    if (order < 0 || order > kMaxOrder) {
        OPENVDB_THROW(openvdb::ValueError, "phase order must be in [0, " << kMaxOrder << "], got "
            << order);
    }
    Truncated t;
    t.f = chi(order + 1);
    // A backward-peaked phase (f < 0) is not what delta-M is for: no scaling then.
    if (t.f < 0.0) t.f = 0.0;
    t.chi.resize(size_t(order) + 1);
    for (int l = 0; l <= order; ++l) t.chi[size_t(l)] = (chi(l) - t.f) / (1.0 - t.f);
    return t;
}

PhaseFunction::Tables
PhaseFunction::tables(const DirectionSet& directions, int order, const openvdb::Vec3d& beam) const
{
    const double f = truncate(order).f;
    const size_t M = size_t(order + 1) * size_t(order + 1), dirs = directions.size();
    Tables t;
    std::vector<double> y(M);
    t.harmonics.resize(dirs * 2 * M);
    t.quadratureMean.assign(M, 0.0);
    for (size_t d = 0; d < dirs; ++d) {
        const double omega = kPi * directions.factor(d);
        for (int sense = 0; sense < 2; ++sense) {
            realSphericalHarmonics(order, sense == 0 ? directions.unit(d) : -directions.unit(d),
                y.data());
            for (size_t lm = 0; lm < M; ++lm) {
                t.harmonics[(2 * d + size_t(sense)) * M + lm] = float(y[lm]);
                t.quadratureMean[lm] += omega * y[lm] / (4.0 * kPi);
            }
        }
    }

    std::vector<double> weight(dirs * 2);
    std::vector<std::pair<double, size_t>> byAngle(dirs * 2);
    for (size_t e = 0; e < dirs * 2; ++e) {
        const openvdb::Vec3d s = (e % 2 == 0 ? 1.0 : -1.0) * directions.unit(e / 2);
        const double mu = std::clamp(s.dot(beam), -1.0, 1.0);
        weight[e] = kPi * directions.factor(e / 2) * value(mu) / (4.0 * kPi * (1.0 - f));
        byAngle[e] = {-mu, e};
    }
    std::sort(byAngle.begin(), byAngle.end());
    // The sampled weights add up to about 1 + f / (1 - f): the forward part delta-M keeps in
    // the beam, plus the quadrature error of the sharp forward peak. Both live in the forward
    // cone, so the directions closest to the beam absorb the difference to exactly 1, and the
    // side and backward weights stay the phase function's own.
    double excess = -1.0;
    for (double w : weight) excess += w;
    for (const auto& [negMu, e] : byAngle) {
        if (excess <= 0.0) break;
        const double take = std::min(excess, weight[e]);
        weight[e] -= take;
        excess -= take;
    }
    if (excess < 0.0) weight[byAngle.front().second] -= excess;
    t.beam.resize(dirs * 2);
    for (size_t e = 0; e < dirs * 2; ++e) {
        t.beam[e] = float(4.0 * kPi * weight[e] / (kPi * directions.factor(e / 2)));
    }
    return t;
}

} // namespace vdbrad
