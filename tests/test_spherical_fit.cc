// Tests of SphericalFit (vdbrad/glossy/SphericalFit.h): least-squares and max-norm fits of values at
// control points on the sphere (thesis §5.2, eqs. 5.1-5.3).
//
// References are computed here independently of the implementation: a dense normal-equations solve
// with partial pivoting (instead of the library's equilibrated sparse LDLT), an enumeration of
// every vertex of the small LPs (instead of GLPK's simplex), an enumeration of the active sets of
// small non-negative least-squares problems (instead of Lawson-Hanson), hand-solved optima, and
// the Karush-Kuhn-Tucker conditions of larger non-negative fits.

#include "vdbrad/glossy/SphericalFit.h"

#include <openvdb/Exceptions.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <random>
#include <utility>
#include <vector>

namespace {

using vdbrad::FitNorm;
using vdbrad::FitOptions;
using vdbrad::FitProblem;
using vdbrad::FitResult;
using Vec3 = std::array<double, 3>;

constexpr FitNorm kNorms[] = {FitNorm::LeastSquares, FitNorm::MaxAbsolute, FitNorm::MaxRelative,
    FitNorm::MaxSqrtScaled};

const char*
normName(FitNorm norm)
{
    switch (norm) {
        case FitNorm::LeastSquares: return "least squares";
        case FitNorm::MaxAbsolute: return "max absolute";
        case FitNorm::MaxRelative: return "max relative";
        case FitNorm::MaxSqrtScaled: return "max sqrt-scaled";
    }
    return "?";
}

/// The statistic each norm minimises (rms for least squares with unit row weights).
double
statistic(const FitResult& r, FitNorm norm)
{
    switch (norm) {
        case FitNorm::LeastSquares: return r.rms;
        case FitNorm::MaxAbsolute: return r.maxAbsolute;
        case FitNorm::MaxRelative: return r.maxRelative;
        case FitNorm::MaxSqrtScaled: return r.maxSqrtScaled;
    }
    return 0.0;
}

FitResult
fit(const FitProblem& p, FitNorm norm, bool nonNegative = false, double ridge = 0.0)
{
    FitOptions o;
    o.norm = norm;
    o.nonNegative = nonNegative;
    o.ridge = ridge;
    return vdbrad::fitControlValues(p, o);
}

// ---- the sphere: an icosahedral grid and interpolation rows --------------------------------

Vec3
normalized(const Vec3& v)
{
    const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return {v[0] / l, v[1] / l, v[2] / l};
}

double
dot(const Vec3& a, const Vec3& b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

struct Icosphere
{
    std::vector<Vec3> vertices;
    std::vector<std::array<uint32_t, 3>> triangles;
    std::vector<std::array<double, 9>> inverse; // per triangle: inverse of [a b c] (columns)
};

/// The icosahedron subdivided @a level times, projected on the sphere: 10 * 4^level + 2
/// vertices (42, 162, 642 for levels 1, 2, 3).
Icosphere
icosphere(int level)
{
    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    Icosphere s;
    for (const Vec3& v : std::vector<Vec3>{{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
             {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1},
             {-t, 0, 1}})
    {
        s.vertices.push_back(normalized(v));
    }
    s.triangles = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9},
        {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
        {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    for (int l = 0; l < level; ++l) {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoints;
        auto midpoint = [&](uint32_t a, uint32_t b) {
            const auto key = std::minmax(a, b);
            auto it = midpoints.find(key);
            if (it != midpoints.end()) return it->second;
            const Vec3 &p = s.vertices[a], &q = s.vertices[b];
            s.vertices.push_back(normalized({p[0] + q[0], p[1] + q[1], p[2] + q[2]}));
            const uint32_t index = uint32_t(s.vertices.size() - 1);
            midpoints.emplace(key, index);
            return index;
        };
        std::vector<std::array<uint32_t, 3>> finer;
        for (const auto& tri : s.triangles) {
            const uint32_t a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]),
                           c = midpoint(tri[2], tri[0]);
            finer.push_back({tri[0], a, c});
            finer.push_back({tri[1], b, a});
            finer.push_back({tri[2], c, b});
            finer.push_back({a, b, c});
        }
        s.triangles = std::move(finer);
    }
    for (const auto& tri : s.triangles) {
        const Vec3 &a = s.vertices[tri[0]], &b = s.vertices[tri[1]], &c = s.vertices[tri[2]];
        // M = [a b c]; inverse = adjugate / det.
        const double m[9] = {a[0], b[0], c[0], a[1], b[1], c[1], a[2], b[2], c[2]};
        const double det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6])
            + m[2] * (m[3] * m[7] - m[4] * m[6]);
        s.inverse.push_back({(m[4] * m[8] - m[5] * m[7]) / det, (m[2] * m[7] - m[1] * m[8]) / det,
            (m[1] * m[5] - m[2] * m[4]) / det, (m[5] * m[6] - m[3] * m[8]) / det,
            (m[0] * m[8] - m[2] * m[6]) / det, (m[2] * m[3] - m[0] * m[5]) / det,
            (m[3] * m[7] - m[4] * m[6]) / det, (m[1] * m[6] - m[0] * m[7]) / det,
            (m[0] * m[4] - m[1] * m[3]) / det});
    }
    return s;
}

/// The interpolation row of direction @a d: the corners of the triangle the ray crosses, with
/// its (gnomonic) barycentric coordinates, normalised to add up to 1.
void
interpolationRow(const Icosphere& s, const Vec3& d, std::vector<uint32_t>& cols,
    std::vector<double>& w)
{
    for (size_t t = 0; t < s.triangles.size(); ++t) {
        const auto& m = s.inverse[t];
        const double u[3] = {m[0] * d[0] + m[1] * d[1] + m[2] * d[2],
            m[3] * d[0] + m[4] * d[1] + m[5] * d[2], m[6] * d[0] + m[7] * d[1] + m[8] * d[2]};
        if (u[0] >= -1e-12 && u[1] >= -1e-12 && u[2] >= -1e-12) {
            const double sum = u[0] + u[1] + u[2];
            cols.assign(s.triangles[t].begin(), s.triangles[t].end());
            w = {u[0] / sum, u[1] / sum, u[2] / sum};
            return;
        }
    }
    FAIL() << "no triangle contains the direction";
}

Vec3
randomDirection(std::mt19937_64& rng)
{
    std::uniform_real_distribution<double> z(-1.0, 1.0), phi(0.0, 2.0 * M_PI);
    const double c = z(rng), s = std::sqrt(std::max(0.0, 1.0 - c * c)), a = phi(rng);
    return {s * std::cos(a), s * std::sin(a), c};
}

/// Henyey-Greenstein around an oblique axis: positive, peaked, not representable exactly.
double
henyeyGreenstein(const Vec3& d, double g)
{
    const Vec3 axis = normalized({0.3, -0.5, 0.8});
    const double mu = dot(d, axis);
    return (1.0 - g * g) / std::pow(1.0 + g * g - 2.0 * g * mu, 1.5);
}

/// A clipped cosine lobe: zero on half the sphere, so linear interpolation undershoots near the
/// terminator and an unconstrained fit goes negative.
double
clippedLobe(const Vec3& d)
{
    return std::pow(std::max(0.0, dot(d, normalized({0.2, 0.1, 1.0}))), 8.0);
}

template<typename F>
FitProblem
sphereProblem(const Icosphere& s, size_t samples, uint64_t seed, F&& function)
{
    FitProblem p;
    p.columns = s.vertices.size();
    std::mt19937_64 rng(seed);
    std::vector<uint32_t> cols;
    std::vector<double> w;
    for (size_t k = 0; k < samples; ++k) {
        const Vec3 d = randomDirection(rng);
        interpolationRow(s, d, cols, w);
        p.addRow(cols, w, function(d, cols, w));
    }
    return p;
}

// ---- independent references ----------------------------------------------------------------

/// Dense copy of the design matrix.
std::vector<std::vector<double>>
denseRows(const FitProblem& p)
{
    std::vector<std::vector<double>> A(p.rows(), std::vector<double>(p.columns, 0.0));
    for (size_t k = 0; k < p.rows(); ++k) {
        for (size_t i = p.rowStart[k]; i < p.rowStart[k + 1]; ++i) A[k][p.column[i]] += p.weight[i];
    }
    return A;
}

/// Solves M x = b by Gaussian elimination with partial pivoting (M square, nonsingular).
std::vector<double>
gaussSolve(std::vector<std::vector<double>> M, std::vector<double> b)
{
    const size_t n = b.size();
    for (size_t c = 0; c < n; ++c) {
        size_t pivot = c;
        for (size_t r = c + 1; r < n; ++r) {
            if (std::abs(M[r][c]) > std::abs(M[pivot][c])) pivot = r;
        }
        std::swap(M[c], M[pivot]);
        std::swap(b[c], b[pivot]);
        for (size_t r = c + 1; r < n; ++r) {
            const double f = M[r][c] / M[c][c];
            for (size_t j = c; j < n; ++j) M[r][j] -= f * M[c][j];
            b[r] -= f * b[c];
        }
    }
    std::vector<double> x(n);
    for (size_t c = n; c-- > 0;) {
        double s = b[c];
        for (size_t j = c + 1; j < n; ++j) s -= M[c][j] * x[j];
        x[c] = s / M[c][c];
    }
    return x;
}

/// Weighted least squares restricted to the columns in @a free (others 0), by dense normal
/// equations.
std::vector<double>
bruteLeastSquares(const FitProblem& p, const std::vector<size_t>& free)
{
    const auto A = denseRows(p);
    const size_t n = free.size();
    std::vector<std::vector<double>> N(n, std::vector<double>(n, 0.0));
    std::vector<double> b(n, 0.0);
    for (size_t k = 0; k < p.rows(); ++k) {
        const double w = p.rowWeight.empty() ? 1.0 : p.rowWeight[k];
        for (size_t i = 0; i < n; ++i) {
            b[i] += w * A[k][free[i]] * p.target[k];
            for (size_t j = 0; j < n; ++j) N[i][j] += w * A[k][free[i]] * A[k][free[j]];
        }
    }
    const auto z = gaussSolve(N, b);
    std::vector<double> x(p.columns, 0.0);
    for (size_t i = 0; i < n; ++i) x[free[i]] = z[i];
    return x;
}

std::vector<double>
bruteLeastSquares(const FitProblem& p)
{
    std::vector<size_t> all(p.columns);
    for (size_t j = 0; j < p.columns; ++j) all[j] = j;
    return bruteLeastSquares(p, all);
}

double
weightedSquares(const FitProblem& p, const std::vector<double>& x)
{
    const auto A = denseRows(p);
    double s = 0.0;
    for (size_t k = 0; k < p.rows(); ++k) {
        double v = -p.target[k];
        for (size_t j = 0; j < p.columns; ++j) v += A[k][j] * x[j];
        s += (p.rowWeight.empty() ? 1.0 : p.rowWeight[k]) * v * v;
    }
    return s;
}

/// Non-negative least squares of a small problem: the best feasible among the unconstrained
/// minimisers over every subset of free columns (the optimum is one of them).
std::vector<double>
bruteNonNegativeLeastSquares(const FitProblem& p)
{
    std::vector<double> best(p.columns, 0.0);
    double bestValue = weightedSquares(p, best);
    for (unsigned mask = 1; mask < (1u << p.columns); ++mask) {
        std::vector<size_t> free;
        for (size_t j = 0; j < p.columns; ++j) {
            if (mask & (1u << j)) free.push_back(j);
        }
        const auto x = bruteLeastSquares(p, free);
        if (*std::min_element(x.begin(), x.end()) < 0.0) continue;
        const double v = weightedSquares(p, x);
        if (v < bestValue) bestValue = v, best = x;
    }
    return best;
}

/// Scale of row k in the max norms, with the documented floor.
double
rowScale(const FitProblem& p, size_t k, FitNorm norm, double valueFloor = FitOptions().valueFloor)
{
    double maxY = 0.0;
    for (double y : p.target) maxY = std::max(maxY, std::abs(y));
    const double d = std::max(std::abs(p.target[k]), valueFloor * maxY);
    if (norm == FitNorm::MaxRelative) return 1.0 / d;
    if (norm == FitNorm::MaxSqrtScaled) return 1.0 / std::sqrt(d);
    return 1.0;
}

/// The max-norm optimum of a small problem (a few columns) by enumerating every vertex of
/// { (x, t) : -t <= s_k (A_k x - Y_k) <= t, x >= 0 if @a nonNegative }: n + 1 constraints tight.
double
bruteMaxNorm(const FitProblem& p, FitNorm norm, bool nonNegative, std::vector<double>& xBest)
{
    const auto A = denseRows(p);
    const size_t n = p.columns, v = n + 1;
    // Constraints c . (x, t) <= r.
    std::vector<std::vector<double>> C;
    std::vector<double> r;
    for (size_t k = 0; k < p.rows(); ++k) {
        const double s = rowScale(p, k, norm);
        for (double sign : {1.0, -1.0}) {
            std::vector<double> c(v);
            for (size_t j = 0; j < n; ++j) c[j] = sign * s * A[k][j];
            c[n] = -1.0;
            C.push_back(c);
            r.push_back(sign * s * p.target[k]);
        }
    }
    if (nonNegative) {
        for (size_t j = 0; j < n; ++j) {
            std::vector<double> c(v, 0.0);
            c[j] = -1.0;
            C.push_back(c);
            r.push_back(0.0);
        }
    }
    double bestT = std::numeric_limits<double>::infinity();
    std::vector<size_t> pick(v);
    // Every v-subset of the constraints, as increasing index tuples.
    for (size_t i = 0; i < v; ++i) pick[i] = i;
    while (true) {
        std::vector<std::vector<double>> M;
        std::vector<double> b;
        for (size_t i : pick) M.push_back(C[i]), b.push_back(r[i]);
        // Skip singular subsets (a zero pivot after elimination).
        auto Mc = M;
        bool singular = false;
        for (size_t c = 0; c < v && !singular; ++c) {
            size_t piv = c;
            for (size_t q = c + 1; q < v; ++q) {
                if (std::abs(Mc[q][c]) > std::abs(Mc[piv][c])) piv = q;
            }
            if (std::abs(Mc[piv][c]) < 1e-12) singular = true;
            std::swap(Mc[c], Mc[piv]);
            for (size_t q = c + 1; q < v && !singular; ++q) {
                const double f = Mc[q][c] / Mc[c][c];
                for (size_t j = c; j < v; ++j) Mc[q][j] -= f * Mc[c][j];
            }
        }
        if (!singular) {
            const auto z = gaussSolve(M, b);
            bool feasible = true;
            for (size_t i = 0; i < C.size() && feasible; ++i) {
                double lhs = 0.0;
                for (size_t j = 0; j < v; ++j) lhs += C[i][j] * z[j];
                feasible = lhs <= r[i] + 1e-12 * (1.0 + std::abs(r[i]));
            }
            if (feasible && z[n] < bestT) {
                bestT = z[n];
                xBest.assign(z.begin(), z.begin() + long(n));
            }
        }
        // Next combination.
        size_t i = v;
        while (i > 0 && pick[i - 1] == C.size() - v + (i - 1)) --i;
        if (i == 0) break;
        ++pick[i - 1];
        for (size_t j = i; j < v; ++j) pick[j] = pick[j - 1] + 1;
    }
    return bestT;
}

FitProblem
constantProblem(const std::vector<double>& targets)
{
    FitProblem p;
    p.columns = 1;
    for (double y : targets) p.addRow({0}, {1.0}, y);
    return p;
}

// ---- tests ---------------------------------------------------------------------------------

TEST(SphericalFit, ExactTargetIsRecoveredByEveryNorm)
{
    // Y = A X0 on an icosahedral grid (sparse rows) and on random dense rows.
    const Icosphere s = icosphere(1);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> value(0.5, 2.0), entry(-1.0, 1.0);
    std::vector<double> x0(s.vertices.size());
    for (double& v : x0) v = value(rng);
    const FitProblem sparse = sphereProblem(s, 3000, 11,
        [&](const Vec3&, const std::vector<uint32_t>& cols, const std::vector<double>& w) {
            return w[0] * x0[cols[0]] + w[1] * x0[cols[1]] + w[2] * x0[cols[2]];
        });
    FitProblem dense;
    dense.columns = 12;
    std::vector<double> xd(dense.columns);
    for (double& v : xd) v = value(rng);
    for (int k = 0; k < 400; ++k) {
        std::vector<double> row(dense.columns);
        double y = 0.0;
        for (size_t j = 0; j < dense.columns; ++j) row[j] = entry(rng), y += row[j] * xd[j];
        dense.addDenseRow(row.data(), y);
    }
    using Case = std::pair<const FitProblem*, const std::vector<double>*>;
    for (const auto& [problem, x] : {Case(&sparse, &x0), Case(&dense, &xd)}) {
        for (FitNorm norm : kNorms) {
            for (bool nonNegative : {false, true}) {
                SCOPED_TRACE(std::string(normName(norm)) + (nonNegative ? ", x >= 0" : "")
                    + (problem == &dense ? ", dense rows" : ", interpolation rows"));
                const FitResult r = fit(*problem, norm, nonNegative);
                ASSERT_EQ(r.x.size(), x->size());
                for (size_t j = 0; j < x->size(); ++j) EXPECT_NEAR(r.x[j], (*x)[j], 1e-8) << j;
                EXPECT_LT(r.maxAbsolute, 1e-9);
                EXPECT_LT(r.maxRelative, 1e-9);
                EXPECT_LT(r.maxSqrtScaled, 1e-9);
                EXPECT_LT(r.rms, 1e-10);
                EXPECT_FALSE(r.rankDeficient);
                EXPECT_EQ(r.lpIterations > 0, norm != FitNorm::LeastSquares);
            }
        }
    }
}

TEST(SphericalFit, LeastSquaresMatchesDenseNormalEquations)
{
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> entry(-1.0, 1.0), weight(0.5, 2.0);
    std::uniform_int_distribution<uint32_t> col(0, 99);
    // Dense rows (the dense path) and 3-nonzero rows over 100 columns (the sparse path), with
    // row weights, repeated columns and a mix of scales.
    FitProblem dense, sparse;
    dense.columns = 15;
    for (int k = 0; k < 300; ++k) {
        std::vector<double> row(dense.columns);
        for (double& v : row) v = entry(rng);
        row[3] *= 1e3;
        dense.addDenseRow(row.data(), 5.0 * entry(rng), weight(rng));
    }
    sparse.columns = 100;
    for (int k = 0; k < 2000; ++k) {
        std::vector<uint32_t> c = {col(rng), col(rng), col(rng)};
        if (k % 50 == 0) c[2] = c[0];
        sparse.addRow(c, {entry(rng), entry(rng), 1e-3 * entry(rng)}, entry(rng), weight(rng));
    }
    for (const FitProblem* p : {&dense, &sparse}) {
        const FitResult r = fit(*p, FitNorm::LeastSquares);
        const auto ref = bruteLeastSquares(*p);
        double scale = 0.0;
        for (double v : ref) scale = std::max(scale, std::abs(v));
        for (size_t j = 0; j < ref.size(); ++j) EXPECT_NEAR(r.x[j], ref[j], 1e-9 * scale) << j;
        EXPECT_FALSE(r.rankDeficient);
        // The statistics agree with residuals() and with a direct evaluation.
        const FitResult again = vdbrad::residuals(*p, r.x);
        EXPECT_EQ(again.maxAbsolute, r.maxAbsolute);
        EXPECT_EQ(again.rms, r.rms);
        const auto A = denseRows(*p);
        double maxAbs = 0.0, sum2 = 0.0;
        for (size_t k = 0; k < p->rows(); ++k) {
            double v = -p->target[k];
            for (size_t j = 0; j < p->columns; ++j) v += A[k][j] * r.x[j];
            maxAbs = std::max(maxAbs, std::abs(v));
            sum2 += v * v;
        }
        EXPECT_NEAR(r.maxAbsolute, maxAbs, 1e-12 * maxAbs);
        EXPECT_NEAR(r.rms, std::sqrt(sum2 / double(p->rows())), 1e-12 * r.rms);
    }
}

TEST(SphericalFit, HandSolvedOptima)
{
    // A constant fitted to {0, 1, 3}: least squares 4/3; max absolute 1.5 with error 1.5.
    const FitProblem three = constantProblem({0.0, 1.0, 3.0});
    FitResult ls = fit(three, FitNorm::LeastSquares), abs = fit(three, FitNorm::MaxAbsolute);
    EXPECT_NEAR(ls.x[0], 4.0 / 3.0, 1e-14);
    EXPECT_NEAR(ls.maxAbsolute, 5.0 / 3.0, 1e-14);
    EXPECT_NEAR(abs.x[0], 1.5, 1e-12);
    EXPECT_NEAR(abs.maxAbsolute, 1.5, 1e-12);
    EXPECT_LE(abs.maxAbsolute, ls.maxAbsolute);

    // A constant fitted to {1, 4}: max absolute 2.5 (error 1.5); max relative equalises
    // (x - 1) / 1 = (4 - x) / 4, x = 1.6, error 0.6; sqrt-scaled equalises (x - 1) / 1 =
    // (4 - x) / 2, x = 2, error 1.
    const FitProblem two = constantProblem({1.0, 4.0});
    abs = fit(two, FitNorm::MaxAbsolute);
    const FitResult rel = fit(two, FitNorm::MaxRelative), sq = fit(two, FitNorm::MaxSqrtScaled);
    EXPECT_NEAR(abs.x[0], 2.5, 1e-12);
    EXPECT_NEAR(abs.maxAbsolute, 1.5, 1e-12);
    EXPECT_NEAR(rel.x[0], 1.6, 1e-12);
    EXPECT_NEAR(rel.maxRelative, 0.6, 1e-12);
    EXPECT_NEAR(sq.x[0], 2.0, 1e-12);
    EXPECT_NEAR(sq.maxSqrtScaled, 1.0, 1e-12);

    // A zero target against the value floor: {0, 1} with denominators max(|Y|, floor max|Y|).
    // Floor 0.5: x / 0.5 = 1 - x, x = 1/3; the default 1e-3: x = 1e-3 / (1 + 1e-3); 1e-6:
    // x = 1e-6 / (1 + 1e-6), i.e. the fit must (nearly) vanish where the target does.
    const FitProblem zero = constantProblem({0.0, 1.0});
    FitOptions o;
    o.norm = FitNorm::MaxRelative;
    o.valueFloor = 0.5;
    FitResult r = vdbrad::fitControlValues(zero, o);
    EXPECT_NEAR(r.x[0], 1.0 / 3.0, 1e-12);
    EXPECT_NEAR(r.maxRelative, 2.0 / 3.0, 1e-12);
    EXPECT_NEAR(vdbrad::residuals(zero, r.x, 0.5).maxRelative, 2.0 / 3.0, 1e-12);
    r = fit(zero, FitNorm::MaxRelative);
    EXPECT_NEAR(r.x[0], 1e-3 / (1.0 + 1e-3), 1e-15);
    EXPECT_NEAR(r.maxRelative, 1.0 / (1.0 + 1e-3), 1e-12);
    EXPECT_EQ(vdbrad::residuals(zero, r.x).maxRelative, r.maxRelative);
    o.valueFloor = 1e-6;
    r = vdbrad::fitControlValues(zero, o);
    EXPECT_NEAR(r.x[0], 1e-6 / (1.0 + 1e-6), 1e-15);
    // x's rounding (1e-16) divided by the floor (1e-6): 1e-10 on the relative error.
    EXPECT_NEAR(r.maxRelative, 1.0 / (1.0 + 1e-6), 1e-9);
    // Sqrt-scaled with floor 1e-6: x / 1e-3 = 1 - x.
    o.norm = FitNorm::MaxSqrtScaled;
    r = vdbrad::fitControlValues(zero, o);
    EXPECT_NEAR(r.x[0], 1e-3 / (1.0 + 1e-3), 1e-14);

    // All targets 0: X = 0 under every norm (no floor to scale by: errors count absolutely).
    FitProblem none;
    none.columns = 2;
    none.addRow({0, 1}, {0.5, 0.5}, 0.0);
    none.addRow({0}, {1.0}, 0.0);
    for (FitNorm norm : kNorms) {
        r = fit(none, norm);
        EXPECT_EQ(r.x, (std::vector<double>{0.0, 0.0})) << normName(norm);
        EXPECT_EQ(r.maxRelative, 0.0) << normName(norm);
    }
    EXPECT_EQ(vdbrad::residuals(none, {1.0, 0.0}).maxRelative, 1.0);
}

TEST(SphericalFit, EachNormIsBestOnItsOwnStatistic)
{
    // A peaked phase function and a clipped lobe (zero on half the sphere, so the value floor
    // matters) on a coarse grid: no fit is exact and the four optima differ.
    const Icosphere s = icosphere(1);
    const FitProblem phase = sphereProblem(s, 3000, 5,
        [](const Vec3& d, const std::vector<uint32_t>&, const std::vector<double>&) {
            return henyeyGreenstein(d, 0.7);
        });
    const FitProblem lobe = sphereProblem(s, 3000, 6,
        [](const Vec3& d, const std::vector<uint32_t>&, const std::vector<double>&) {
            return clippedLobe(d);
        });
    for (const FitProblem* p : {&phase, &lobe}) {
        for (bool nonNegative : {false, true}) {
            SCOPED_TRACE(std::string(p == &phase ? "phase" : "lobe")
                + (nonNegative ? ", x >= 0" : ""));
            std::vector<FitResult> results;
            for (FitNorm norm : kNorms) results.push_back(fit(*p, norm, nonNegative));
            for (size_t a = 0; a < results.size(); ++a) {
                const double own = statistic(results[a], kNorms[a]);
                for (size_t b = 0; b < results.size(); ++b) {
                    if (a == b) continue;
                    const double other = statistic(results[b], kNorms[a]);
                    EXPECT_LE(own, other * (1.0 + 1e-9))
                        << normName(kNorms[a]) << " vs " << normName(kNorms[b]);
                    // Not vacuous: the optima differ by more than rounding.
                    EXPECT_GT(other, own * 1.001)
                        << normName(kNorms[a]) << " vs " << normName(kNorms[b]);
                }
            }
            if (nonNegative) {
                for (const auto& r : results) {
                    EXPECT_GE(*std::min_element(r.x.begin(), r.x.end()), 0.0);
                }
            }
        }
    }
}

TEST(SphericalFit, MaxNormOptimaAreCertifiedByTheirActiveRows)
{
    // The optimum over a subset of the rows is at most the optimum over all of them; so if the
    // rows where a solution's error is (nearly) largest, fitted alone, cannot do better than
    // it, the solution is optimal. 20,000 interpolation rows and 2,500 dense rows, more than
    // one LP's worth of either, so that the solver's row generation is exercised. (At GLPK's
    // default optimality tolerance this caught optima ~1e-8 too high.)
    const Icosphere s = icosphere(2);
    const FitProblem sparse = sphereProblem(s, 20000, 31,
        [](const Vec3& d, const std::vector<uint32_t>&, const std::vector<double>&) {
            return henyeyGreenstein(d, 0.6);
        });
    FitProblem dense;
    dense.columns = 16;
    std::mt19937_64 rng(37);
    for (int k = 0; k < 2500; ++k) {
        // The monomials x^a y^b z^c of degrees 2 and 3 (6 + 10): on the sphere they span the
        // harmonics of orders 0 to 3, 16 independent functions.
        const Vec3 d = randomDirection(rng);
        std::vector<double> row;
        for (int degree : {2, 3}) {
            for (int a = 0; a <= degree; ++a) {
                for (int b = 0; a + b <= degree; ++b) {
                    row.push_back(
                        std::pow(d[0], a) * std::pow(d[1], b) * std::pow(d[2], degree - a - b));
                }
            }
        }
        ASSERT_EQ(row.size(), dense.columns);
        dense.addDenseRow(row.data(), henyeyGreenstein(d, 0.5));
    }
    for (const FitProblem* p : {&sparse, static_cast<const FitProblem*>(&dense)}) {
        for (FitNorm norm : {FitNorm::MaxAbsolute, FitNorm::MaxRelative, FitNorm::MaxSqrtScaled}) {
            for (bool nonNegative : {false, true}) {
                SCOPED_TRACE(std::string(normName(norm)) + (nonNegative ? ", x >= 0" : "")
                    + (p == &dense ? ", dense rows" : ", interpolation rows"));
                const FitResult r = fit(*p, norm, nonNegative);
                const double t = statistic(r, norm);
                // The active rows, plus the largest target (it sets the value floor).
                FitProblem active;
                active.columns = p->columns;
                size_t largest = 0;
                for (size_t k = 0; k < p->rows(); ++k) {
                    if (std::abs(p->target[k]) > std::abs(p->target[largest])) largest = k;
                }
                for (size_t k = 0; k < p->rows(); ++k) {
                    double v = -p->target[k];
                    for (size_t i = p->rowStart[k]; i < p->rowStart[k + 1]; ++i) {
                        v += p->weight[i] * r.x[p->column[i]];
                    }
                    if (std::abs(v) * rowScale(*p, k, norm) >= t * (1.0 - 1e-6) || k == largest) {
                        active.addRow(&p->column[p->rowStart[k]], &p->weight[p->rowStart[k]],
                            p->rowStart[k + 1] - p->rowStart[k], p->target[k]);
                    }
                }
                EXPECT_LT(active.rows(), 200u);
                EXPECT_GE(active.rows(), 2u);
                const FitResult sub = fit(active, norm, nonNegative);
                EXPECT_NEAR(statistic(sub, norm), t, 1e-9 * t);
            }
        }
    }
}

TEST(SphericalFit, SmallMaxNormsMatchVertexEnumeration)
{
    // Two control points interpolated linearly along a segment, with targets a line cannot
    // follow (one of them 0); every max norm against every vertex of its LP.
    FitProblem p;
    p.columns = 2;
    const double u[] = {0.0, 0.2, 0.45, 0.7, 0.85, 1.0}, y[] = {0.0, 0.3, 0.2, 1.5, 2.5, 2.0};
    for (int k = 0; k < 6; ++k) p.addRow({0, 1}, {1.0 - u[k], u[k]}, y[k]);
    for (FitNorm norm : {FitNorm::MaxAbsolute, FitNorm::MaxRelative, FitNorm::MaxSqrtScaled}) {
        for (bool nonNegative : {false, true}) {
            SCOPED_TRACE(std::string(normName(norm)) + (nonNegative ? ", x >= 0" : ""));
            std::vector<double> xBest;
            const double best = bruteMaxNorm(p, norm, nonNegative, xBest);
            const FitResult r = fit(p, norm, nonNegative);
            EXPECT_NEAR(statistic(r, norm), best, 1e-10 * best);
            EXPECT_NEAR(r.x[0], xBest[0], 1e-9);
            EXPECT_NEAR(r.x[1], xBest[1], 1e-9);
        }
    }
}

TEST(SphericalFit, NonNegativeIsTheConstrainedOptimum)
{
    // Two control points, samples on the half u >= 0.5 of the segment near the line 4u - 1:
    // every unconstrained fit extrapolates x0 ~ -1; the constrained optimum refits x1 with
    // x0 = 0, which clamping would not.
    FitProblem p;
    p.columns = 2;
    const double u[] = {0.5, 0.6, 0.75, 0.9, 1.0}, y[] = {1.0, 1.45, 2.1, 2.6, 3.0};
    for (int k = 0; k < 5; ++k) p.addRow({0, 1}, {1.0 - u[k], u[k]}, y[k]);
    for (FitNorm norm : kNorms) {
        SCOPED_TRACE(normName(norm));
        const FitResult free = fit(p, norm, false), bounded = fit(p, norm, true);
        EXPECT_LT(free.x[0], -0.5);
        EXPECT_GE(bounded.x[0], 0.0);
        EXPECT_GE(bounded.x[1], 0.0);
        EXPECT_GT(std::abs(bounded.x[1] - free.x[1]), 0.01);
        if (norm == FitNorm::LeastSquares) {
            const auto ref = bruteNonNegativeLeastSquares(p);
            EXPECT_NEAR(bounded.x[0], ref[0], 1e-12);
            EXPECT_NEAR(bounded.x[1], ref[1], 1e-12);
            // Better than clamping the unconstrained solution.
            EXPECT_LT(weightedSquares(p, bounded.x),
                weightedSquares(p, {0.0, free.x[1]}) - 1e-3);
        } else {
            std::vector<double> xBest;
            const double best = bruteMaxNorm(p, norm, true, xBest);
            EXPECT_NEAR(statistic(bounded, norm), best, 1e-10 * best);
            EXPECT_NEAR(bounded.x[0], xBest[0], 1e-9);
            EXPECT_NEAR(bounded.x[1], xBest[1], 1e-9);
            EXPECT_GT(statistic(bounded, norm), statistic(free, norm) * 1.01);
        }
    }
    // A constant fitted to {-3, 1}: unconstrained -1 (least squares, max absolute), 0 (max
    // relative: (x + 3) / 3 = 1 - x), (sqrt 3 - 3) / (1 + sqrt 3) (sqrt-scaled:
    // (x + 3) / sqrt 3 = 1 - x); non-negative 0 for all.
    const FitProblem c = constantProblem({-3.0, 1.0});
    const double expected[] = {-1.0, -1.0, 0.0, (std::sqrt(3.0) - 3.0) / (1.0 + std::sqrt(3.0))};
    for (size_t i = 0; i < 4; ++i) {
        EXPECT_NEAR(fit(c, kNorms[i], false).x[0], expected[i], 1e-12) << normName(kNorms[i]);
        EXPECT_NEAR(fit(c, kNorms[i], true).x[0], 0.0, 1e-12) << normName(kNorms[i]);
    }
}

TEST(SphericalFit, RandomSmallProblemsMatchEnumeration)
{
    // Random small problems (2-5 unknowns, 6-10 rows, positive targets) against the exhaustive
    // references: every active set for non-negative least squares, every vertex for the LPs.
    std::mt19937_64 rng(41);
    std::uniform_real_distribution<double> entry(-1.0, 1.0), target(0.05, 2.0);
    for (int trial = 0; trial < 40; ++trial) {
        FitProblem p;
        p.columns = 2 + size_t(trial % 4);
        const int rows = 6 + trial % 5;
        for (int k = 0; k < rows; ++k) {
            std::vector<uint32_t> cols;
            std::vector<double> w;
            for (uint32_t j = 0; j < p.columns; ++j) cols.push_back(j), w.push_back(entry(rng));
            p.addRow(cols, w, target(rng));
        }
        SCOPED_TRACE("trial " + std::to_string(trial));
        const auto ref = bruteNonNegativeLeastSquares(p);
        const FitResult ls = fit(p, FitNorm::LeastSquares, true);
        const double best = weightedSquares(p, ref);
        EXPECT_NEAR(weightedSquares(p, ls.x), best, 1e-12 * (1.0 + best));
        for (size_t j = 0; j < p.columns; ++j) EXPECT_NEAR(ls.x[j], ref[j], 1e-8) << j;
        if (p.columns > 3) continue; // vertex enumeration grows as rows^(columns + 1)
        for (FitNorm norm : {FitNorm::MaxAbsolute, FitNorm::MaxRelative, FitNorm::MaxSqrtScaled}) {
            for (bool nonNegative : {false, true}) {
                std::vector<double> xBest;
                const double t = bruteMaxNorm(p, norm, nonNegative, xBest);
                const FitResult r = fit(p, norm, nonNegative);
                EXPECT_NEAR(statistic(r, norm), t, 1e-10 * t) << normName(norm) << nonNegative;
            }
        }
    }
}

TEST(SphericalFit, NonNegativeLeastSquaresSatisfiesOptimalityConditions)
{
    // A clipped lobe on 162 control points, three sparse subsets of three columns, and a dense
    // case: check x >= 0 and the KKT conditions of min |W^(1/2) (A x - Y)|^2 with an independent
    // gradient g = A^T W (Y - A x): g_j = 0 where x_j > 0, g_j <= 0 where x_j = 0.
    const Icosphere s = icosphere(2);
    FitProblem lobe = sphereProblem(s, 6000, 17,
        [](const Vec3& d, const std::vector<uint32_t>&, const std::vector<double>&) {
            return clippedLobe(d);
        });
    std::mt19937_64 rng(23);
    std::uniform_real_distribution<double> entry(-1.0, 1.0);
    FitProblem dense;
    dense.columns = 40;
    for (int k = 0; k < 500; ++k) {
        std::vector<double> row(dense.columns);
        for (double& v : row) v = entry(rng);
        dense.addDenseRow(row.data(), entry(rng), 0.5 + 0.5 * (entry(rng) + 1.0));
    }
    for (FitProblem* p : {&lobe, &dense}) {
        const FitResult free = fit(*p, FitNorm::LeastSquares);
        const FitResult r = fit(*p, FitNorm::LeastSquares, true);
        EXPECT_LT(*std::min_element(free.x.begin(), free.x.end()), 0.0);
        EXPECT_GE(*std::min_element(r.x.begin(), r.x.end()), 0.0);
        const auto A = denseRows(*p);
        std::vector<double> g(p->columns, 0.0), g0(p->columns, 0.0);
        for (size_t k = 0; k < p->rows(); ++k) {
            const double w = p->rowWeight.empty() ? 1.0 : p->rowWeight[k];
            double v = p->target[k];
            for (size_t j = 0; j < p->columns; ++j) v -= A[k][j] * r.x[j];
            for (size_t j = 0; j < p->columns; ++j) {
                g[j] += w * A[k][j] * v;
                g0[j] += w * A[k][j] * p->target[k];
            }
        }
        double scale = 0.0;
        for (double v : g0) scale = std::max(scale, std::abs(v));
        size_t atBound = 0;
        for (size_t j = 0; j < p->columns; ++j) {
            if (r.x[j] > 0.0) {
                EXPECT_NEAR(g[j], 0.0, 1e-9 * scale) << j;
            } else {
                EXPECT_LE(g[j], 1e-9 * scale) << j;
                ++atBound;
            }
        }
        EXPECT_GT(atBound, 0u);
        // The constrained optimum is no worse than the clamped unconstrained one.
        std::vector<double> clamped = free.x;
        for (double& v : clamped) v = std::max(v, 0.0);
        EXPECT_LT(weightedSquares(*p, r.x), weightedSquares(*p, clamped));
    }
}

TEST(SphericalFit, UndeterminedColumns)
{
    // Column 2 is untouched and columns 0 and 1 are identical: the normal equations are
    // singular. Without ridge: the minimum-norm solution (x2 = 0, x0 = x1 = half the one-column
    // fit); with ridge: x2 = 0 and a slightly shrunk fit.
    FitProblem p;
    p.columns = 3;
    const double y[] = {1.0, 2.0, 4.0};
    for (int k = 0; k < 3; ++k) p.addRow({0, 1}, {double(k + 1), double(k + 1)}, y[k]);
    // One column c (values 1, 2, 3) fitted to y: c = (1 + 4 + 12) / 14.
    const double c = 17.0 / 14.0;
    FitResult r = fit(p, FitNorm::LeastSquares);
    EXPECT_TRUE(r.rankDeficient);
    EXPECT_NEAR(r.x[0], c / 2.0, 1e-9);
    EXPECT_NEAR(r.x[1], c / 2.0, 1e-9);
    EXPECT_EQ(r.x[2], 0.0);
    // Ridge r: (14 + r) x0 + 14 x1 = 17 and symmetrically, x0 = x1 = 17 / (28 + r).
    r = fit(p, FitNorm::LeastSquares, false, 1e-3);
    EXPECT_FALSE(r.rankDeficient);
    EXPECT_NEAR(r.x[0], 17.0 / 28.001, 1e-12);
    EXPECT_NEAR(r.x[1], 17.0 / 28.001, 1e-12);
    EXPECT_EQ(r.x[2], 0.0);
    // Non-negative too (the duplicate pair is positive, so nothing changes).
    r = fit(p, FitNorm::LeastSquares, true);
    EXPECT_NEAR(r.x[0] + r.x[1], c, 1e-9);
    EXPECT_EQ(r.x[2], 0.0);
    // The LPs pin the untouched column at 0 and still reach the optimum of the pair.
    for (FitNorm norm : {FitNorm::MaxAbsolute, FitNorm::MaxRelative, FitNorm::MaxSqrtScaled}) {
        r = fit(p, norm);
        EXPECT_EQ(r.x[2], 0.0);
        FitProblem single;
        single.columns = 1;
        for (int k = 0; k < 3; ++k) single.addRow({0}, {2.0 * (k + 1)}, y[k]);
        std::vector<double> xBest;
        EXPECT_NEAR(statistic(r, norm), bruteMaxNorm(single, norm, false, xBest), 1e-12);
    }
}

TEST(SphericalFit, RowLayout)
{
    // Repeated columns add up; addRow's three forms build the same arrays.
    FitProblem a, b;
    a.columns = b.columns = 3;
    a.addRow({2, 0, 2}, {0.25, 1.0, 0.25}, 3.0);
    const uint32_t cols[] = {2, 0, 2};
    const double w[] = {0.25, 1.0, 0.25};
    b.addRow(cols, w, 3, 3.0);
    EXPECT_EQ(a.rowStart, b.rowStart);
    EXPECT_EQ(a.column, b.column);
    EXPECT_TRUE(a.rowWeight.empty());
    a.addRow({1}, {1.0}, 1.0, 4.0);
    ASSERT_EQ(a.rowWeight.size(), 2u);
    EXPECT_EQ(a.rowWeight[0], 1.0);
    EXPECT_EQ(a.rowWeight[1], 4.0);
    const double dense[] = {1.0, 2.0, 3.0};
    a.addDenseRow(dense, 14.0);
    EXPECT_EQ(a.rows(), 3u);
    EXPECT_EQ(a.rowStart, (std::vector<size_t>{0, 3, 4, 7}));
    EXPECT_EQ(a.rowWeight.size(), 3u);
    // x = (1, 1, 4): 1 + 0.5 * 4 = 3, 1, 1 + 2 + 12 = 15 (residual 1).
    const FitResult r = vdbrad::residuals(a, {1.0, 1.0, 4.0});
    EXPECT_NEAR(r.maxAbsolute, 1.0, 1e-15);
    EXPECT_NEAR(r.rms, std::sqrt(1.0 / 3.0), 1e-15);
    EXPECT_NEAR(r.maxRelative, 1.0 / 14.0, 1e-15);
    EXPECT_NEAR(r.maxSqrtScaled, 1.0 / std::sqrt(14.0), 1e-15);
    // Three independent rows, three unknowns: every norm solves them, x1 = 1,
    // x0 + 0.5 x2 = 3, x0 + 3 x2 = 12, so x = (1.2, 1, 3.6).
    for (FitNorm norm : kNorms) {
        const FitResult f = fit(a, norm);
        EXPECT_LT(f.maxAbsolute, 1e-12) << normName(norm);
        EXPECT_NEAR(f.x[0], 1.2, 1e-12) << normName(norm);
        EXPECT_NEAR(f.x[1], 1.0, 1e-12) << normName(norm);
        EXPECT_NEAR(f.x[2], 3.6, 1e-12) << normName(norm);
    }
}

TEST(SphericalFit, MalformedProblemsThrow)
{
    const auto good = [] {
        FitProblem p;
        p.columns = 2;
        p.addRow({0, 1}, {0.5, 0.5}, 1.0);
        p.addRow({1}, {1.0}, 2.0);
        return p;
    };
    ASSERT_NO_THROW(vdbrad::fitControlValues(good()));
    using Mutation = void (*)(FitProblem&);
    const Mutation mutations[] = {
        [](FitProblem& p) { p = FitProblem(); p.columns = 2; },                   // no rows
        [](FitProblem& p) { p.columns = 0; },                                     // no columns
        [](FitProblem& p) { p.column[1] = 2; },                                   // out of range
        [](FitProblem& p) { p.target[0] = std::nan(""); },                        // NaN target
        [](FitProblem& p) { p.weight[0] = std::numeric_limits<double>::infinity(); },
        [](FitProblem& p) { p.rowStart.pop_back(); },                             // short CSR
        [](FitProblem& p) { p.rowStart[1] = 3; p.rowStart[2] = 2; },              // decreasing
        [](FitProblem& p) { p.weight.pop_back(); },                               // short weights
        [](FitProblem& p) { p.rowWeight = {1.0}; },                               // short weights
        [](FitProblem& p) { p.rowWeight = {1.0, -1.0}; },                         // negative
        [](FitProblem& p) { p.rowWeight = {1.0, std::nan("")}; },
    };
    for (const Mutation& m : mutations) {
        FitProblem p = good();
        m(p);
        for (FitNorm norm : kNorms) EXPECT_THROW(fit(p, norm), openvdb::ValueError);
        EXPECT_THROW(vdbrad::residuals(p, {0.0, 0.0}), openvdb::ValueError);
    }
    FitOptions o;
    o.ridge = -1.0;
    EXPECT_THROW(vdbrad::fitControlValues(good(), o), openvdb::ValueError);
    o.ridge = std::numeric_limits<double>::infinity();
    EXPECT_THROW(vdbrad::fitControlValues(good(), o), openvdb::ValueError);
    o = FitOptions();
    for (double floor : {0.0, -1.0, 2.0, std::nan("")}) {
        o.valueFloor = floor;
        EXPECT_THROW(vdbrad::fitControlValues(good(), o), openvdb::ValueError);
        EXPECT_THROW(vdbrad::residuals(good(), {0.0, 0.0}, floor), openvdb::ValueError);
    }
    EXPECT_THROW(vdbrad::residuals(good(), {0.0}), openvdb::ValueError);
    EXPECT_THROW(vdbrad::residuals(good(), {0.0, std::nan("")}), openvdb::ValueError);
    FitProblem p;
    EXPECT_THROW(p.addRow({0, 1}, {1.0}, 0.0), openvdb::ValueError);
}

TEST(SphericalFit, Timing)
{
    // 20,000 samples of a phase function on 162 control points (3 nonzeros per row): printed,
    // not asserted (CI machines vary); each fit is still checked to be a fit.
    const Icosphere s = icosphere(2);
    const FitProblem p = sphereProblem(s, 20000, 29,
        [](const Vec3& d, const std::vector<uint32_t>&, const std::vector<double>&) {
            return henyeyGreenstein(d, 0.5);
        });
    const FitResult ls = fit(p, FitNorm::LeastSquares);
    for (bool nonNegative : {false, true}) {
        for (FitNorm norm : kNorms) {
            const FitResult r = fit(p, norm, nonNegative);
            std::cout << "[ timing   ] 20000 x 162, " << std::setw(15) << normName(norm)
                      << (nonNegative ? ", x >= 0: " : ":         ") << std::fixed
                      << std::setprecision(3) << r.seconds << " s";
            if (r.lpIterations) std::cout << " (" << r.lpIterations << " simplex iterations)";
            std::cout << std::scientific << std::setprecision(3) << "  maxAbs " << r.maxAbsolute
                      << " maxRel " << r.maxRelative << " maxSqrt " << r.maxSqrtScaled << " rms "
                      << r.rms << std::defaultfloat << "\n";
            EXPECT_LE(statistic(r, norm), statistic(ls, norm) * (1.0 + 1e-9));
        }
    }
}

} // namespace
