#include "vdbrad/glossy/SphericalHarmonics.h"
#include "vdbrad/core/Constants.h"
#include "vdbrad/sweep/RealHarmonics.h"


#include <openvdb/Exceptions.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>

namespace vdbrad {

namespace {

constexpr size_t kMaxSize = size_t(SphericalHarmonics::kMaxOrder + 1)
    * size_t(SphericalHarmonics::kMaxOrder + 1);

void
checkOrder(int order)
{
    if (order < 0 || order > SphericalHarmonics::kMaxOrder) {
        OPENVDB_THROW(openvdb::ValueError, "spherical harmonics order must be in [0, "
            << SphericalHarmonics::kMaxOrder << "], got " << order);
    }
}

/// out_l = D^l in_l for bands 0..order, the blocks @a D stored one after the other.
void
applyBlocks(const double* D, int order, const double* in, double* out)
{
    for (int l = 0; l <= order; ++l) {
        const int dim = 2 * l + 1;
        const double* x = in + l * l;
        double* y = out + l * l;
        for (int i = 0; i < dim; ++i, D += dim) {
            double s = 0.0;
            for (int j = 0; j < dim; ++j) s += D[j] * x[j];
            y[i] = s;
        }
    }
}

} // namespace

SphericalHarmonics::SphericalHarmonics(int order) : mOrder(order)
{
    checkOrder(order);
    // Ivanic & Ruedenberg's Table 1 (with the 1998 erratum): for band l and entry (m, n),
    //   u = sqrt((l + m)(l - m) / d),  v = (1 - 2 delta_m0) / 2 sqrt((1 + delta_m0)
    //   (l + |m| - 1)(l + |m|) / d),  w = -(1 - delta_m0) / 2 sqrt((l - |m| - 1)(l - |m|) / d),
    // d = (l + n)(l - n) for |n| < l, else 2l (2l - 1). Table 2's V for |m| = 1 has a single
    // term with factor sqrt(2): folded into v here.
    const size_t total = Rotation::blockOffset(order + 1);
    mU.assign(total, 0.0);
    mV.assign(total, 0.0);
    mW.assign(total, 0.0);
    for (int l = 2; l <= order; ++l) {
        const size_t base = Rotation::blockOffset(l), dim = size_t(2 * l + 1);
        for (int m = -l; m <= l; ++m) {
            const int am = std::abs(m);
            const double d0 = m == 0 ? 1.0 : 0.0;
            for (int n = -l; n <= l; ++n) {
                const double den = std::abs(n) < l ? double((l + n) * (l - n))
                    : double(2 * l * (2 * l - 1));
                const size_t e = base + size_t(m + l) * dim + size_t(n + l);
                mU[e] = std::sqrt((l + m) * (l - m) / den);
                mV[e] = 0.5 * std::sqrt((1.0 + d0) * (l + am - 1) * (l + am) / den)
                    * (1.0 - 2.0 * d0) * (am == 1 ? std::sqrt(2.0) : 1.0);
                mW[e] = -0.5 * std::sqrt((l - am - 1) * (l - am) / den) * (1.0 - d0);
            }
        }
    }
}

void
SphericalHarmonics::basis(const openvdb::math::Vec3d& dir, double* out) const
{
    realSphericalHarmonics(mOrder, dir, out);
}

double
SphericalHarmonics::evaluate(const double* coeffs, const openvdb::math::Vec3d& dir) const
{
    std::array<double, kMaxSize> y;
    realSphericalHarmonics(mOrder, dir, y.data());
    double sum = 0.0;
    for (size_t i = 0, n = size(); i < n; ++i) sum += coeffs[i] * y[i];
    return sum;
}

std::vector<double>
SphericalHarmonics::project(const std::vector<openvdb::math::Vec3d>& dirs,
    const std::vector<double>& weights, const std::vector<double>& values) const
{
    if (weights.size() != dirs.size() || values.size() != dirs.size()) {
        OPENVDB_THROW(openvdb::ValueError, "projection needs as many weights and values as "
            "directions, got " << dirs.size() << " directions, " << weights.size()
            << " weights, " << values.size() << " values");
    }
    const size_t M = size();
    std::vector<double> c(M, 0.0);
    std::array<double, kMaxSize> y;
    for (size_t k = 0; k < dirs.size(); ++k) {
        realSphericalHarmonics(mOrder, dirs[k], y.data());
        const double wv = weights[k] * values[k];
        for (size_t i = 0; i < M; ++i) c[i] += wv * y[i];
    }
    return c;
}

std::vector<double>
SphericalHarmonics::fit(const std::vector<openvdb::math::Vec3d>& dirs,
    const std::vector<double>& values, double lambda) const
{
    if (values.size() != dirs.size()) {
        OPENVDB_THROW(openvdb::ValueError, "fit needs one value per direction, got "
            << dirs.size() << " directions and " << values.size() << " values");
    }
    if (!(lambda >= 0.0 && std::isfinite(lambda))) {
        OPENVDB_THROW(openvdb::ValueError, "fit regularisation must be finite and >= 0, got "
            << lambda);
    }
    const size_t M = size(), N = dirs.size();
    if (lambda == 0.0 && N < M) {
        OPENVDB_THROW(openvdb::ValueError, "an order-" << mOrder << " fit needs at least " << M
            << " samples without regularisation, got " << N);
    }
    // Tikhonov as extra rows: || [A; sqrt(lambda) I] c - [v; 0] ||^2 is the regularised sum.
    const Eigen::Index rows = Eigen::Index(N + (lambda > 0.0 ? M : 0));
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(rows, Eigen::Index(M));
    Eigen::VectorXd b = Eigen::VectorXd::Zero(rows);
    std::array<double, kMaxSize> y;
    for (size_t k = 0; k < N; ++k) {
        realSphericalHarmonics(mOrder, dirs[k], y.data());
        for (size_t i = 0; i < M; ++i) A(Eigen::Index(k), Eigen::Index(i)) = y[i];
        b(Eigen::Index(k)) = values[k];
    }
    if (lambda > 0.0) {
        const double s = std::sqrt(lambda);
        for (size_t i = 0; i < M; ++i) A(Eigen::Index(N + i), Eigen::Index(i)) = s;
    }
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
    if (qr.rank() < Eigen::Index(M)) {
        OPENVDB_THROW(openvdb::ValueError, "the " << N << " samples determine only " << qr.rank()
            << " of the " << M << " order-" << mOrder << " coefficients; add samples or set "
            "lambda > 0");
    }
    const Eigen::VectorXd x = qr.solve(b);
    return std::vector<double>(x.data(), x.data() + x.size());
}

void
SphericalHarmonics::scale(double s, double* coeffs, size_t n)
{
    for (size_t i = 0; i < n; ++i) coeffs[i] *= s;
}

void
SphericalHarmonics::add(const double* a, double* b, size_t n)
{
    for (size_t i = 0; i < n; ++i) b[i] += a[i];
}

SphericalHarmonics::Rotation
SphericalHarmonics::rotation(const openvdb::math::Mat3d& R) const
{
    double err = 0.0;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            double dot = 0.0;
            for (int k = 0; k < 3; ++k) dot += R(k, i) * R(k, j);
            err = std::max(err, std::abs(dot - (i == j ? 1.0 : 0.0)));
        }
    }
    const double det = R.det();
    if (!(err <= 1e-6 && std::abs(det - 1.0) <= 1e-6)) {
        OPENVDB_THROW(openvdb::ValueError, "not a proper rotation: |R^T R - I| = " << err
            << ", det = " << det);
    }

    Rotation r;
    r.mOrder = mOrder;
    r.mBlocks.assign(Rotation::blockOffset(mOrder + 1), 0.0);
    r.mBlocks[0] = 1.0;
    if (mOrder == 0) return r;
    // Band 1: R with rows and columns in the harmonics' order (y, z, x).
    static constexpr int kAxis[3] = {1, 2, 0};
    double* d1 = r.mBlocks.data() + 1;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) d1[i * 3 + j] = R(kAxis[i], kAxis[j]);
    }
    // r1(i, j), i, j in -1..1.
    const auto r1 = [d1](int i, int j) { return d1[(i + 1) * 3 + j + 1]; };

    for (int l = 2; l <= mOrder; ++l) {
        const int dim = 2 * l + 1, pdim = 2 * l - 1;
        const double* prev = r.mBlocks.data() + Rotation::blockOffset(l - 1);
        double* cur = r.mBlocks.data() + Rotation::blockOffset(l);
        const size_t base = Rotation::blockOffset(l);
        // D^{l-1}(a, b), a, b in -(l-1)..l-1.
        const auto dp = [prev, pdim, l](int a, int b) {
            return prev[(a + l - 1) * pdim + b + l - 1];
        };
        // Ivanic & Ruedenberg's P^i_{a,b}: band l - 1 coupled to band 1's row i.
        const auto P = [&](int i, int a, int b) {
            if (b == l) return r1(i, 1) * dp(a, l - 1) - r1(i, -1) * dp(a, 1 - l);
            if (b == -l) return r1(i, 1) * dp(a, 1 - l) + r1(i, -1) * dp(a, l - 1);
            return r1(i, 0) * dp(a, b);
        };
        for (int m = -l; m <= l; ++m) {
            for (int n = -l; n <= l; ++n) {
                const size_t e = base + size_t((m + l) * dim + n + l);
                // u vanishes for |m| = l and w for |m| >= l - 1, where P's first index would
                // leave band l - 1.
                double x = 0.0;
                if (std::abs(m) < l) x += mU[e] * P(0, m, n);
                double V;
                if (m == 0) V = P(1, 1, n) + P(-1, -1, n);
                else if (m == 1) V = P(1, 0, n);
                else if (m == -1) V = P(-1, 0, n);
                else if (m > 0) V = P(1, m - 1, n) - P(-1, 1 - m, n);
                else V = P(1, m + 1, n) + P(-1, -m - 1, n);
                x += mV[e] * V;
                if (m != 0 && std::abs(m) < l - 1) {
                    const double W = m > 0 ? P(1, m + 1, n) + P(-1, -m - 1, n)
                        : P(1, m - 1, n) - P(-1, 1 - m, n);
                    x += mW[e] * W;
                }
                cur[(m + l) * dim + n + l] = x;
            }
        }
    }
    return r;
}

void
SphericalHarmonics::Rotation::apply(const double* in, double* out) const
{
    applyBlocks(mBlocks.data(), mOrder, in, out);
}

void
SphericalHarmonics::rotate(const Rotation& r, const double* in, double* out) const
{
    if (r.order() < mOrder) {
        OPENVDB_THROW(openvdb::ValueError, "an order-" << r.order()
            << " rotation cannot rotate an order-" << mOrder << " expansion");
    }
    // Blocks are stored band by band, so a higher-order rotation's first bands serve as well.
    applyBlocks(r.mBlocks.data(), mOrder, in, out);
}

std::vector<double>
SphericalHarmonics::zonal(const std::vector<double>& z, const openvdb::math::Vec3d& axis) const
{
    const double len = axis.length();
    if (!(len > 0.0 && std::isfinite(len))) {
        OPENVDB_THROW(openvdb::ValueError, "zonal axis must be non-zero and finite, got " << axis);
    }
    std::vector<double> c(size(), 0.0);
    std::array<double, kMaxSize> y;
    realSphericalHarmonics(mOrder, axis, y.data());
    const int top = std::min(mOrder, int(z.size()) - 1);
    for (int l = 0; l <= top; ++l) {
        const double f = std::sqrt(4.0 * kPi / (2 * l + 1)) * z[size_t(l)];
        for (int i = l * l; i < (l + 1) * (l + 1); ++i) c[size_t(i)] = f * y[size_t(i)];
    }
    return c;
}

std::vector<double>
SphericalHarmonics::zonalCoefficients(int order, const std::function<double(double)>& h,
    int points)
{
    checkOrder(order);
    if (points < 0) {
        OPENVDB_THROW(openvdb::ValueError, "zonal quadrature points must be >= 0, got " << points);
    }
    if (points == 0) points = 2 * (order + 1) + 16;
    std::vector<double> x, w;
    gaussLegendre(points, x, w);
    std::vector<double> z(size_t(order) + 1, 0.0);
    for (int half = 0; half < 2; ++half) {
        for (size_t k = 0; k < x.size(); ++k) {
            // [-1, 1] mapped onto [-1, 0] or [0, 1].
            const double mu = 0.5 * (x[k] + (half == 0 ? -1.0 : 1.0)), hw = 0.5 * w[k] * h(mu);
            double p0 = 1.0, p1 = mu;
            for (int l = 0; l <= order; ++l) {
                double pl = l == 0 ? 1.0 : mu;
                if (l >= 2) {
                    pl = ((2 * l - 1) * mu * p1 - (l - 1) * p0) / l;
                    p0 = p1;
                    p1 = pl;
                }
                z[size_t(l)] += hw * pl;
            }
        }
    }
    for (int l = 0; l <= order; ++l) {
        z[size_t(l)] *= 2.0 * kPi * std::sqrt((2 * l + 1) / (4.0 * kPi));   // 2 pi Y_l0 / P_l
    }
    return z;
}

void
gaussLegendre(int n, std::vector<double>& nodes, std::vector<double>& weights)
{
    if (n < 1) OPENVDB_THROW(openvdb::ValueError, "Gauss-Legendre needs n >= 1, got " << n);
    nodes.assign(size_t(n), 0.0);
    weights.assign(size_t(n), 0.0);
    // P_n(x) and P_{n-1}(x) by the three-term recurrence.
    auto legendre = [n](double x, double& pn, double& pm) {
        double p0 = 1.0, p1 = x;
        for (int k = 2; k <= n; ++k) {
            const double pk = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
            p0 = p1;
            p1 = pk;
        }
        pn = p1;
        pm = p0;
    };
    // Newton on P_n from the asymptotic guess (Abramowitz & Stegun 22.16.6); nodes are
    // symmetric, so only half are solved for. P_n' = n (x P_n - P_{n-1}) / (x^2 - 1).
    for (int i = 0; i < (n + 1) / 2; ++i) {
        double x = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 1.0, pn = 0.0, pm = 0.0;
        for (int it = 0; it < 100; ++it) {
            legendre(x, pn, pm);
            dp = n * (x * pn - pm) / (x * x - 1.0);
            const double dx = pn / dp;
            x -= dx;
            if (std::abs(dx) <= 1e-15) break;
        }
        legendre(x, pn, pm);
        dp = n * (x * pn - pm) / (x * x - 1.0);
        nodes[size_t(i)] = -x;
        nodes[size_t(n - 1 - i)] = x;
        weights[size_t(i)] = weights[size_t(n - 1 - i)] = 2.0 / ((1.0 - x * x) * dp * dp);
    }
}

} // namespace vdbrad
