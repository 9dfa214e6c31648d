// Tests of SphericalHarmonics (vdbrad/glossy/SphericalHarmonics.h): real spherical-harmonic expansions
// beside ControlPoints, with the same operations (query, projection, fit, rotation).
//
// References are independent of the implementation where possible: closed forms of the
// low-order harmonics (which pin down the sign convention), exact polynomial moments for the
// Gauss-Legendre rule, the definition g(w) = f(R^T w) evaluated pointwise for rotations (the
// rotation matrices built here from quaternions, not by the library), Ramamoorthi and
// Hanrahan's clamped-cosine coefficients for the zonal integrals, and Eigen's LDLT on the
// normal equations for the regularised fit.

#include "RandomDirection.h"
#include "vdbrad/core/Constants.h"
#include "vdbrad/glossy/SphericalHarmonics.h"

#include <openvdb/Exceptions.h>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

namespace {

using vdbrad::kPi;

using vdbrad::SphericalHarmonics;
using openvdb::math::Mat3d;
using openvdb::math::Vec3d;


using vdbrad::test::randomDirection;

std::vector<double>
randomCoeffs(size_t n, std::mt19937_64& rng)
{
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<double> c(n);
    for (double& x : c) x = u(rng);
    return c;
}

/// A uniformly random proper rotation for column vectors (w' = R w), from a random unit
/// quaternion (w, x, y, z) by the textbook formula.
Mat3d
randomRotation(std::mt19937_64& rng)
{
    std::normal_distribution<double> g;
    double q[4], n = 0.0;
    for (double& c : q) { c = g(rng); n += c * c; }
    n = std::sqrt(n);
    const double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    return Mat3d(1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y));
}

/// Gauss-Legendre in mu times uniform phi: exact for harmonics products up to degree 2L when
/// given L + 1 nodes in mu and 2L + 2 in phi.
void
sphereQuadrature(int L, std::vector<Vec3d>& dirs, std::vector<double>& weights)
{
    std::vector<double> mu, wmu;
    vdbrad::gaussLegendre(L + 1, mu, wmu);
    const int nphi = 2 * L + 2;
    dirs.clear();
    weights.clear();
    for (size_t i = 0; i < mu.size(); ++i) {
        const double s = std::sqrt(1.0 - mu[i] * mu[i]);
        for (int j = 0; j < nphi; ++j) {
            const double phi = 2.0 * kPi * (j + 0.5) / nphi;
            dirs.emplace_back(s * std::cos(phi), s * std::sin(phi), mu[i]);
            weights.push_back(wmu[i] * 2.0 * kPi / nphi);
        }
    }
}

double
maxAbsDiff(const std::vector<double>& a, const std::vector<double>& b)
{
    double m = 0.0;
    for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
    return m;
}

// ---- basis and quadrature ---------------------------------------------------------------------

TEST(SphericalHarmonics, GaussLegendreIntegratesPolynomialsExactly)
{
    for (int n : {1, 2, 5, 17, 64}) {
        std::vector<double> x, w;
        vdbrad::gaussLegendre(n, x, w);
        // int_{-1}^{1} x^k dx = 2 / (k + 1) for even k, 0 for odd, exact for k <= 2n - 1.
        for (int k = 0; k <= 2 * n - 1; ++k) {
            double sum = 0.0;
            for (int i = 0; i < n; ++i) sum += w[size_t(i)] * std::pow(x[size_t(i)], k);
            const double exact = k % 2 == 0 ? 2.0 / (k + 1) : 0.0;
            EXPECT_NEAR(sum, exact, 1e-14) << "n = " << n << ", k = " << k;
        }
    }
}

TEST(SphericalHarmonics, LowOrdersMatchClosedFormsWithoutCondonShortley)
{
    // The sign convention the rotation relies on: Y_1,-1..Y_11 = +sqrt(3/4pi) (y, z, x), and
    // no (-1)^m at l = 2 either.
    const SphericalHarmonics sh(2);
    std::mt19937_64 rng(1);
    for (int t = 0; t < 20; ++t) {
        const Vec3d d = randomDirection(rng);
        const double x = d.x(), y = d.y(), z = d.z();
        double Y[9];
        sh.basis(d * 3.7, Y);   // not unit on purpose
        const double c1 = std::sqrt(3.0 / (4.0 * kPi)), c2 = std::sqrt(15.0 / (4.0 * kPi));
        const double expected[9] = {0.5 / std::sqrt(kPi), c1 * y, c1 * z, c1 * x, c2 * x * y,
            c2 * y * z, std::sqrt(5.0 / (16.0 * kPi)) * (3 * z * z - 1), c2 * x * z,
            0.5 * c2 * (x * x - y * y)};
        for (int i = 0; i < 9; ++i) EXPECT_NEAR(Y[i], expected[i], 1e-14) << "index " << i;
    }
}

TEST(SphericalHarmonics, BasisIsOrthonormal)
{
    // Products up to degree 2L = 24 integrate exactly on the Gauss-Legendre x phi grid.
    const int L = 12;
    const SphericalHarmonics sh(L);
    std::vector<Vec3d> dirs;
    std::vector<double> w;
    sphereQuadrature(L, dirs, w);
    const size_t M = sh.size();
    std::vector<double> gram(M * M, 0.0), y(M);
    for (size_t k = 0; k < dirs.size(); ++k) {
        sh.basis(dirs[k], y.data());
        for (size_t i = 0; i < M; ++i) {
            for (size_t j = 0; j < M; ++j) gram[i * M + j] += w[k] * y[i] * y[j];
        }
    }
    double err = 0.0;
    for (size_t i = 0; i < M; ++i) {
        for (size_t j = 0; j < M; ++j) err = std::max(err, std::abs(gram[i * M + j] - (i == j)));
    }
    std::printf("  orthonormality, order %d: max |G - I| = %.2e\n", L, err);
    EXPECT_LT(err, 1e-10);
}

// ---- projection and fit -----------------------------------------------------------------------

TEST(SphericalHarmonics, ProjectionRecoversBandLimitedFunction)
{
    const int L = 8;
    const SphericalHarmonics sh(L);
    std::mt19937_64 rng(2);
    const std::vector<double> c = randomCoeffs(sh.size(), rng);
    std::vector<Vec3d> dirs;
    std::vector<double> w, v;
    sphereQuadrature(L, dirs, w);
    for (const Vec3d& d : dirs) v.push_back(sh.evaluate(c.data(), d));
    EXPECT_LT(maxAbsDiff(sh.project(dirs, w, v), c), 1e-12);   // exact quadrature: rounding only
}

TEST(SphericalHarmonics, FitRecoversBandLimitedFunction)
{
    const int L = 8;
    const SphericalHarmonics sh(L);
    std::mt19937_64 rng(3);
    const std::vector<double> c = randomCoeffs(sh.size(), rng);
    std::vector<Vec3d> dirs;
    std::vector<double> v;
    for (int k = 0; k < 300; ++k) {   // random samples, 300 > 81 coefficients
        dirs.push_back(randomDirection(rng));
        v.push_back(sh.evaluate(c.data(), dirs.back()));
    }
    const double err = maxAbsDiff(sh.fit(dirs, v), c);
    std::printf("  fit of an order-%d function from 300 random samples: max error %.2e\n", L, err);
    EXPECT_LT(err, 1e-9);

    // Samples on the upper hemisphere only (a BRDF's domain) still determine it exactly.
    dirs.clear();
    v.clear();
    for (int k = 0; k < 300; ++k) {
        Vec3d d = randomDirection(rng);
        if (d.z() < 0.0) d = -d;
        dirs.push_back(d);
        v.push_back(sh.evaluate(c.data(), d));
    }
    const double errHemi = maxAbsDiff(sh.fit(dirs, v), c);
    std::printf("  same from 300 upper-hemisphere samples: max error %.2e\n", errHemi);
    EXPECT_LT(errHemi, 1e-9);
}

TEST(SphericalHarmonics, FitErrorOfLobeDecreasesWithOrder)
{
    // A Phong-like lobe max(0, w . a)^8 around an oblique axis, fitted from 3000 random samples,
    // its RMS error measured on 3000 others. Its even part is (w . a)^8 / 2, a polynomial of
    // degree 8, so even bands above 8 are zero and orders 10 and 12 gain nothing over 9 and 11
    // (they only fit the noise-free samples' rounding): the error must fall with every order
    // up to 9, and with every second order throughout.
    std::mt19937_64 rng(4);
    const Vec3d a = Vec3d(0.3, -0.5, 0.8).unit();
    const auto lobe = [&](const Vec3d& d) { return std::pow(std::max(0.0, d.dot(a)), 8.0); };
    std::vector<Vec3d> train, test;
    std::vector<double> vt;
    for (int k = 0; k < 3000; ++k) {
        train.push_back(randomDirection(rng));
        vt.push_back(lobe(train.back()));
        test.push_back(randomDirection(rng));
    }
    std::vector<double> rms;
    for (int L = 0; L <= 12; ++L) {
        const SphericalHarmonics sh(L);
        const std::vector<double> c = sh.fit(train, vt);
        double sum = 0.0;
        for (const Vec3d& d : test) {
            const double e = sh.evaluate(c.data(), d) - lobe(d);
            sum += e * e;
        }
        rms.push_back(std::sqrt(sum / test.size()));
        std::printf("  lobe max(0,cos)^8: order %2d, %3zu coefficients, RMS error %.3e\n", L,
            sh.size(), rms.back());
        if (L >= 1 && L <= 9) {
            EXPECT_LT(rms[size_t(L)], rms[size_t(L - 1)]) << "order " << L;
        }
        if (L >= 2) {
            EXPECT_LT(rms[size_t(L)], rms[size_t(L - 2)]) << "order " << L;
        }
    }
    EXPECT_LT(rms.back(), 1e-4 * rms.front());
}

TEST(SphericalHarmonics, RegularisedFitSolvesTikhonovNormalEquations)
{
    const int L = 6;
    const SphericalHarmonics sh(L);
    std::mt19937_64 rng(5);
    std::vector<Vec3d> dirs;
    std::vector<double> v;
    for (int k = 0; k < 200; ++k) {
        dirs.push_back(randomDirection(rng));
        v.push_back(std::exp(dirs.back().x()) * std::sin(3.0 * dirs.back().y()));
    }
    const double lambda = 0.3;
    const std::vector<double> c = sh.fit(dirs, v, lambda);
    // Reference: (A^T A + lambda I) c = A^T v by Eigen's LDLT.
    const Eigen::Index M = Eigen::Index(sh.size()), N = Eigen::Index(dirs.size());
    Eigen::MatrixXd A(N, M);
    std::vector<double> y(sh.size());
    for (Eigen::Index k = 0; k < N; ++k) {
        sh.basis(dirs[size_t(k)], y.data());
        for (Eigen::Index i = 0; i < M; ++i) A(k, i) = y[size_t(i)];
    }
    const Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(v.data(), N);
    const Eigen::MatrixXd normal = A.transpose() * A + lambda * Eigen::MatrixXd::Identity(M, M);
    const Eigen::VectorXd ref = normal.ldlt().solve(A.transpose() * b);
    for (Eigen::Index i = 0; i < M; ++i) EXPECT_NEAR(c[size_t(i)], ref(i), 1e-10);

    // Samples on the equator only leave Y_10 (and the other odd-in-z harmonics) undetermined:
    // refused without lambda, fine with it.
    std::vector<Vec3d> ring;
    std::vector<double> rv;
    for (int k = 0; k < 100; ++k) {
        ring.emplace_back(std::cos(0.1 * k), std::sin(0.1 * k), 0.0);
        rv.push_back(1.0);
    }
    EXPECT_THROW(SphericalHarmonics(2).fit(ring, rv), openvdb::ValueError);
    const std::vector<double> cr = SphericalHarmonics(2).fit(ring, rv, 1e-6);
    EXPECT_NEAR(cr[2], 0.0, 1e-12);   // Y_10's coefficient: nothing pulls it from 0
}

// ---- zonal lobes ------------------------------------------------------------------------------

TEST(SphericalHarmonics, ZonalCoefficientsOfClampedCosine)
{
    // Ramamoorthi & Hanrahan 2001: max(0, mu) has A_l = sqrt(4pi / (2l + 1)) z_l = pi, 2pi/3,
    // then 0 for odd l > 1 and 2pi (-1)^(l/2 - 1) / ((l + 2)(l - 1)) l! / (2^l (l/2)!^2) for
    // even l. Piecewise linear times P_l: the split rule is exact, so rounding only.
    const int L = 12;
    const std::vector<double> z = SphericalHarmonics::zonalCoefficients(L,
        [](double mu) { return std::max(0.0, mu); });
    ASSERT_EQ(z.size(), size_t(L + 1));
    for (int l = 0; l <= L; ++l) {
        double A;
        if (l == 0) A = kPi;
        else if (l == 1) A = 2.0 * kPi / 3.0;
        else if (l % 2 == 1) A = 0.0;
        else {
            const double binom = std::tgamma(l + 1.0)
                / (std::pow(2.0, l) * std::pow(std::tgamma(l / 2 + 1.0), 2));
            A = 2.0 * kPi * ((l / 2 - 1) % 2 == 0 ? 1.0 : -1.0) / ((l + 2) * (l - 1)) * binom;
        }
        EXPECT_NEAR(std::sqrt(4.0 * kPi / (2 * l + 1)) * z[size_t(l)], A, 1e-13) << "l = " << l;
    }
}

TEST(SphericalHarmonics, ZonalExpansionEvaluatesTheLobe)
{
    // sum_l z_l Y_l0 at cos = w . a, checked through evaluate() against the Legendre series
    // written out: h_L(mu) = sum_l z_l sqrt((2l + 1)/4pi) P_l(mu).
    const int L = 10;
    const SphericalHarmonics sh(L);
    const std::vector<double> z = SphericalHarmonics::zonalCoefficients(L,
        [](double mu) { return std::pow(std::max(0.0, mu), 5.0); });
    std::mt19937_64 rng(6);
    const Vec3d a = randomDirection(rng);
    const std::vector<double> c = sh.zonal(z, a * 2.5);   // axis need not be unit
    for (int t = 0; t < 50; ++t) {
        const Vec3d w = randomDirection(rng);
        const double mu = w.dot(a);
        double p0 = 1.0, p1 = mu, h = z[0] * std::sqrt(1.0 / (4.0 * kPi));
        for (int l = 1; l <= L; ++l) {
            const double pl = l == 1 ? mu : ((2 * l - 1) * mu * p1 - (l - 1) * p0) / l;
            if (l >= 2) { p0 = p1; p1 = pl; }
            h += z[size_t(l)] * std::sqrt((2 * l + 1) / (4.0 * kPi)) * pl;
        }
        EXPECT_NEAR(sh.evaluate(c.data(), w), h, 1e-12);
    }
    // Order 10 is above the lobe's degree 5 plus its kink: close to the lobe itself.
    double maxErr = 0.0;
    for (int t = 0; t < 200; ++t) {
        const Vec3d w = randomDirection(rng);
        maxErr = std::max(maxErr, std::abs(sh.evaluate(c.data(), w)
            - std::pow(std::max(0.0, w.dot(a)), 5.0)));
    }
    std::printf("  max(0,cos)^5 at order %d: max pointwise error %.3e\n", L, maxErr);
    EXPECT_LT(maxErr, 0.05);
}

// ---- rotation ---------------------------------------------------------------------------------

TEST(SphericalHarmonics, RotationMatchesPointwiseDefinition)
{
    // g = rotate(f) must satisfy g(R w) = f(w) for every w (g(w) = f(R^T w)).
    std::mt19937_64 rng(7);
    double worst = 0.0;
    for (int L = 0; L <= 10; ++L) {
        const SphericalHarmonics sh(L);
        for (int trial = 0; trial < 5; ++trial) {
            const Mat3d R = randomRotation(rng);
            const std::vector<double> f = randomCoeffs(sh.size(), rng);
            std::vector<double> g(sh.size());
            sh.rotate(sh.rotation(R), f.data(), g.data());
            for (int t = 0; t < 20; ++t) {
                const Vec3d w = randomDirection(rng);
                const double e = std::abs(sh.evaluate(g.data(), R * w) - sh.evaluate(f.data(), w));
                worst = std::max(worst, e);
                ASSERT_LT(e, 1e-10) << "order " << L;
            }
        }
    }
    std::printf("  rotation, orders 0-10: max |g(R w) - f(w)| = %.2e\n", worst);
}

TEST(SphericalHarmonics, RotationIsOrthogonalPerBand)
{
    // Each block is orthogonal, so every band's norm is kept; checked up to the highest order,
    // where the recurrences have run longest.
    std::mt19937_64 rng(8);
    const SphericalHarmonics sh(SphericalHarmonics::kMaxOrder);
    const SphericalHarmonics::Rotation r = sh.rotation(randomRotation(rng));
    double worstOrth = 0.0, worstNorm = 0.0;
    const std::vector<double> f = randomCoeffs(sh.size(), rng);
    std::vector<double> g(sh.size());
    sh.rotate(r, f.data(), g.data());
    for (int l = 0; l <= sh.order(); ++l) {
        const int dim = 2 * l + 1;
        const double* D = r.block(l);
        for (int i = 0; i < dim; ++i) {
            for (int j = 0; j < dim; ++j) {
                double dot = 0.0;
                for (int k = 0; k < dim; ++k) dot += D[i * dim + k] * D[j * dim + k];
                worstOrth = std::max(worstOrth, std::abs(dot - (i == j)));
            }
        }
        double nf = 0.0, ng = 0.0;
        for (int i = l * l; i < (l + 1) * (l + 1); ++i) {
            nf += f[size_t(i)] * f[size_t(i)];
            ng += g[size_t(i)] * g[size_t(i)];
        }
        worstNorm = std::max(worstNorm, std::abs(std::sqrt(ng) - std::sqrt(nf)));
    }
    std::printf("  order %d: max |D D^T - I| = %.2e, max band-norm change %.2e\n", sh.order(),
        worstOrth, worstNorm);
    EXPECT_LT(worstOrth, 1e-10);
    EXPECT_LT(worstNorm, 1e-10);
}

TEST(SphericalHarmonics, RotationComposesAndIdentityIsIdentity)
{
    std::mt19937_64 rng(9);
    const SphericalHarmonics sh(10);
    const Mat3d A = randomRotation(rng), B = randomRotation(rng);
    const std::vector<double> f = randomCoeffs(sh.size(), rng);
    std::vector<double> a(sh.size()), ba(sh.size()), direct(sh.size()), same(sh.size());
    // Rotating by A then by B is rotating by B A (column vectors).
    sh.rotate(sh.rotation(A), f.data(), a.data());
    sh.rotate(sh.rotation(B), a.data(), ba.data());
    sh.rotate(sh.rotation(B * A), f.data(), direct.data());
    EXPECT_LT(maxAbsDiff(ba, direct), 1e-12);

    const SphericalHarmonics::Rotation id = sh.rotation(Mat3d::identity());
    sh.rotate(id, f.data(), same.data());
    EXPECT_LT(maxAbsDiff(same, f), 1e-14);

    // A higher-order rotation rotates a lower-order expansion (its first bands).
    const SphericalHarmonics low(4);
    std::vector<double> lowOut(low.size());
    low.rotate(sh.rotation(A), f.data(), lowOut.data());
    for (size_t i = 0; i < low.size(); ++i) EXPECT_NEAR(lowOut[i], a[i], 1e-15);
}

TEST(SphericalHarmonics, RotatedZonalLobeIsTheLobeAroundTheRotatedAxis)
{
    // Column-vector convention: the lobe around z rotated by R is the lobe around R * z. First
    // a quarter turn about z written out (x goes to y), then random rotations.
    const int L = 10;
    const SphericalHarmonics sh(L);
    const std::vector<double> z = SphericalHarmonics::zonalCoefficients(L,
        [](double mu) { return std::pow(std::max(0.0, mu), 20.0); });
    std::vector<double> out(sh.size());

    const Mat3d quarter(0, -1, 0,
                        1, 0, 0,
                        0, 0, 1);
    EXPECT_LT(((quarter * Vec3d(1, 0, 0)) - Vec3d(0, 1, 0)).length(), 1e-15);
    sh.rotate(sh.rotation(quarter), sh.zonal(z, Vec3d(1, 0, 0)).data(), out.data());
    EXPECT_LT(maxAbsDiff(out, sh.zonal(z, Vec3d(0, 1, 0))), 1e-13);

    std::mt19937_64 rng(10);
    const std::vector<double> aroundZ = sh.zonal(z, Vec3d(0, 0, 1));
    for (int trial = 0; trial < 10; ++trial) {
        const Mat3d R = randomRotation(rng);
        sh.rotate(sh.rotation(R), aroundZ.data(), out.data());
        EXPECT_LT(maxAbsDiff(out, sh.zonal(z, R * Vec3d(0, 0, 1))), 1e-12);
    }

    // OpenVDB's own rotation<Mat3d>(axis, angle) is for row vectors (v * M): its transpose is
    // the matrix to pass here.
    const Mat3d vdb = openvdb::math::rotation<Mat3d>(Vec3d(1, 0, 0), 0.7);
    const Vec3d moved = Vec3d(0, 0, 1) * vdb;
    sh.rotate(sh.rotation(vdb.transpose()), aroundZ.data(), out.data());
    EXPECT_LT(maxAbsDiff(out, sh.zonal(z, moved)), 1e-12);
}

// ---- invalid input ----------------------------------------------------------------------------

TEST(SphericalHarmonics, InvalidInputThrows)
{
    EXPECT_THROW(SphericalHarmonics(-1), openvdb::ValueError);
    EXPECT_THROW(SphericalHarmonics(SphericalHarmonics::kMaxOrder + 1), openvdb::ValueError);
    EXPECT_NO_THROW(SphericalHarmonics(0));

    const SphericalHarmonics sh(3);
    const Mat3d reflection(1, 0, 0, 0, 1, 0, 0, 0, -1);
    const Mat3d scaled = Mat3d::identity() * 1.01;
    const Mat3d shear(1.0, 0.1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    const Mat3d nan(std::nan(""), 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0);
    EXPECT_THROW(sh.rotation(reflection), openvdb::ValueError);
    EXPECT_THROW(sh.rotation(scaled), openvdb::ValueError);
    EXPECT_THROW(sh.rotation(shear), openvdb::ValueError);
    EXPECT_THROW(sh.rotation(nan), openvdb::ValueError);
    EXPECT_THROW(sh.rotation(Mat3d::zero()), openvdb::ValueError);

    std::vector<double> in(SphericalHarmonics(5).size()), out(in.size());
    EXPECT_THROW(SphericalHarmonics(5).rotate(sh.rotation(Mat3d::identity()), in.data(),
        out.data()), openvdb::ValueError);

    const std::vector<Vec3d> dirs(20, Vec3d(0, 0, 1));
    EXPECT_THROW(sh.project(dirs, std::vector<double>(19), std::vector<double>(20)),
        openvdb::ValueError);
    EXPECT_THROW(sh.project(dirs, std::vector<double>(20), std::vector<double>(21)),
        openvdb::ValueError);
    EXPECT_THROW(sh.fit(dirs, std::vector<double>(19)), openvdb::ValueError);
    EXPECT_THROW(sh.fit(dirs, std::vector<double>(20), -1.0), openvdb::ValueError);
    EXPECT_THROW(sh.fit(dirs, std::vector<double>(20), std::nan("")), openvdb::ValueError);
    // 10 samples for 16 coefficients; 20 copies of one direction (rank 1).
    EXPECT_THROW(sh.fit(std::vector<Vec3d>(10, Vec3d(1, 0, 0)), std::vector<double>(10)),
        openvdb::ValueError);
    EXPECT_THROW(sh.fit(dirs, std::vector<double>(20)), openvdb::ValueError);

    EXPECT_THROW(sh.zonal({1.0}, Vec3d(0, 0, 0)), openvdb::ValueError);
    EXPECT_THROW(sh.zonal({1.0}, Vec3d(std::nan(""), 0, 1)), openvdb::ValueError);
    const auto one = [](double) { return 1.0; };
    EXPECT_THROW(SphericalHarmonics::zonalCoefficients(-1, one), openvdb::ValueError);
    EXPECT_THROW(SphericalHarmonics::zonalCoefficients(33, one), openvdb::ValueError);
    EXPECT_THROW(SphericalHarmonics::zonalCoefficients(3, one, -2), openvdb::ValueError);
    std::vector<double> x, w;
    EXPECT_THROW(vdbrad::gaussLegendre(0, x, w), openvdb::ValueError);
}

// ---- timing (printed, not asserted) -----------------------------------------------------------

TEST(SphericalHarmonics, RotationTiming)
{
    using Clock = std::chrono::steady_clock;
    std::mt19937_64 rng(11);
    double sink = 0.0;
    for (int L : {2, 4, 8, 12, 16, 32}) {
        const SphericalHarmonics sh(L);
        const Mat3d R = randomRotation(rng);
        const int builds = std::max(20, 200000 / (L * L * L));
        auto t0 = Clock::now();
        for (int i = 0; i < builds; ++i) sink += sh.rotation(R).block(L)[0];
        const double build = std::chrono::duration<double>(Clock::now() - t0).count() / builds;

        const SphericalHarmonics::Rotation r = sh.rotation(R);
        std::vector<double> f = randomCoeffs(sh.size(), rng), g(sh.size());
        const int applies = builds * 10;
        t0 = Clock::now();
        for (int i = 0; i < applies; ++i) {
            sh.rotate(r, f.data(), g.data());
            f[0] = g[0];   // keep the loop from being hoisted
        }
        const double apply = std::chrono::duration<double>(Clock::now() - t0).count() / applies;

        const int queries = applies;
        t0 = Clock::now();
        for (int i = 0; i < queries; ++i) {
            sink += sh.evaluate(g.data(), Vec3d(0.3, 0.4 + 1e-9 * i, 0.5));
        }
        const double query = std::chrono::duration<double>(Clock::now() - t0).count() / queries;
        std::printf("  order %2d (%4zu coefficients): rotation() %8.2f us, rotate() %8.3f us, "
            "evaluate() %7.3f us\n", L, sh.size(), build * 1e6, apply * 1e6, query * 1e6);
    }
    EXPECT_TRUE(std::isfinite(sink));
}

} // namespace
