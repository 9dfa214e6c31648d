// SphericalFit: least squares through the normal equations (Eigen); the max norms, linear
// programs solved by GLPK's simplex method, are in MaxNormFit.cc.
//
// Least squares forms N = A^T W A (+ ridge I) and b = A^T W Y. The problems this serves are tall
// and narrow (up to ~50,000 rows x 642 control points, or 40,000 x 289 harmonics): N is at most a
// few hundred columns wide, so forming it costs one pass over the rows and solving it is cheap,
// whereas a QR of A itself (SparseQR, or a dense QR of a 40,000 x 289 matrix) costs far more
// time and memory for accuracy that these well-conditioned interpolation matrices do not need.
// N is equilibrated (unit diagonal) so that a control point only grazed by samples is not
// mistaken for an undetermined one. Interpolation rows (3 nonzeros) give a sparse N, factored by
// SimplicialLDLT; dense rows (harmonics) give a dense N, accumulated block by block with
// rank-k updates and factored by a dense LDLT. Either falls back to a complete orthogonal
// decomposition (the minimum-norm solution) when a pivot shows N singular: a control point no
// sample touches, or columns the samples cannot tell apart.
//
// Non-negative least squares is Lawson & Hanson's active-set method on the same normal
// equations, warm-started from the unconstrained solution's positive part: typically only a few
// unknowns are pinned at 0, so it takes a few steps instead of one per unknown.
#include "vdbrad/glossy/SphericalFit.h"

#include "vdbrad/glossy/MaxNormFit.h"

#include <openvdb/Exceptions.h>

#include <Eigen/Dense>
#include <Eigen/Sparse>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <limits>

namespace vdbrad {

void
FitProblem::addRow(const uint32_t* cols, const double* w, size_t count, double y,
    double leastSquaresWeight)
{
    if (rowStart.empty()) rowStart.push_back(0);
    if (count > 0) {
        column.insert(column.end(), cols, cols + count);
        weight.insert(weight.end(), w, w + count);
    }
    rowStart.push_back(column.size());
    // Weights are stored only once one differs from 1; earlier rows then get 1.
    if (leastSquaresWeight != 1.0 || !rowWeight.empty()) {
        rowWeight.resize(target.size(), 1.0);
        rowWeight.push_back(leastSquaresWeight);
    }
    target.push_back(y);
}

void
FitProblem::addRow(const std::vector<uint32_t>& cols, const std::vector<double>& w, double y,
    double leastSquaresWeight)
{
    if (cols.size() != w.size()) {
        OPENVDB_THROW(openvdb::ValueError, "FitProblem::addRow: " << cols.size()
            << " columns but " << w.size() << " weights");
    }
    addRow(cols.data(), w.data(), cols.size(), y, leastSquaresWeight);
}

void
FitProblem::addDenseRow(const double* w, double y, double leastSquaresWeight)
{
    std::vector<uint32_t> cols(columns);
    for (size_t j = 0; j < columns; ++j) cols[j] = uint32_t(j);
    addRow(cols.data(), w, columns, y, leastSquaresWeight);
}

namespace fit {

double
maxAbsTarget(const FitProblem& p)
{
    double maxY = 0.0;
    for (double y : p.target) maxY = std::max(maxY, std::abs(y));
    return maxY;
}

} // namespace fit

namespace {

using Clock = std::chrono::steady_clock;
using Vector = Eigen::VectorXd;
using SparseMatrix = Eigen::SparseMatrix<double>;

/// A pivot of the equilibrated normal matrix (unit diagonal) below this marks it singular: the
/// columns' condition number would exceed 1e6, beyond what normal equations resolve.
constexpr double kRankTolerance = 1e-12;

double
secondsSince(Clock::time_point start)
{
    return std::chrono::duration<double>(Clock::now() - start).count();
}

void
validate(const FitProblem& p)
{
    const size_t m = p.rows();
    if (m == 0) OPENVDB_THROW(openvdb::ValueError, "fit: the problem has no rows");
    if (p.columns == 0) OPENVDB_THROW(openvdb::ValueError, "fit: the problem has no columns");
    // GLPK numbers columns with int (and one more for t).
    if (p.columns >= size_t(INT_MAX)) {
        OPENVDB_THROW(openvdb::ValueError, "fit: " << p.columns << " columns are too many");
    }
    if (p.rowStart.size() != m + 1) {
        OPENVDB_THROW(openvdb::ValueError, "fit: rowStart has " << p.rowStart.size()
            << " entries for " << m << " rows (needs rows + 1)");
    }
    if (p.rowStart.front() != 0 || p.rowStart.back() != p.column.size()
        || p.weight.size() != p.column.size())
    {
        OPENVDB_THROW(openvdb::ValueError, "fit: rowStart (" << p.rowStart.front() << " .. "
            << p.rowStart.back() << "), column (" << p.column.size() << ") and weight ("
            << p.weight.size() << ") disagree");
    }
    for (size_t k = 0; k < m; ++k) {
        if (p.rowStart[k + 1] < p.rowStart[k]) {
            OPENVDB_THROW(openvdb::ValueError, "fit: rowStart decreases at row " << k);
        }
        if (!std::isfinite(p.target[k])) {
            OPENVDB_THROW(openvdb::ValueError, "fit: target " << k << " is " << p.target[k]);
        }
    }
    for (size_t i = 0; i < p.column.size(); ++i) {
        if (p.column[i] >= p.columns) {
            OPENVDB_THROW(openvdb::ValueError, "fit: column " << p.column[i]
                << " out of range (" << p.columns << " columns)");
        }
        if (!std::isfinite(p.weight[i])) {
            OPENVDB_THROW(openvdb::ValueError, "fit: weight " << i << " is " << p.weight[i]);
        }
    }
    if (!p.rowWeight.empty()) {
        if (p.rowWeight.size() != m) {
            OPENVDB_THROW(openvdb::ValueError, "fit: " << p.rowWeight.size()
                << " row weights for " << m << " rows");
        }
        for (size_t k = 0; k < m; ++k) {
            if (!(p.rowWeight[k] >= 0.0) || !std::isfinite(p.rowWeight[k])) {
                OPENVDB_THROW(openvdb::ValueError, "fit: row weight " << k << " is "
                    << p.rowWeight[k] << " (must be finite and >= 0)");
            }
        }
    }
}

void
validateFloor(double valueFloor)
{
    if (!(valueFloor > 0.0 && valueFloor <= 1.0)) {
        OPENVDB_THROW(openvdb::ValueError, "fit: valueFloor " << valueFloor
            << " outside (0, 1]");
    }
}

/// The relative measures' denominator floor; 1 when every target is 0 (any fit is then measured
/// absolutely, and X = 0 is exact for all of them).
double
denominatorFloor(const FitProblem& p, double valueFloor)
{
    const double maxY = fit::maxAbsTarget(p);
    if (maxY == 0.0) return 1.0;
    return std::max(valueFloor * maxY, std::numeric_limits<double>::min());
}

void
fillStatistics(const FitProblem& p, const std::vector<double>& x, double valueFloor,
    FitResult& result)
{
    const double floor = denominatorFloor(p, valueFloor);
    double maxAbs = 0.0, maxRel = 0.0, maxSqrt = 0.0, sum2 = 0.0;
    for (size_t k = 0; k < p.rows(); ++k) {
        double v = 0.0;
        for (size_t i = p.rowStart[k]; i < p.rowStart[k + 1]; ++i) {
            v += p.weight[i] * x[p.column[i]];
        }
        const double r = std::abs(v - p.target[k]);
        const double d = std::max(std::abs(p.target[k]), floor);
        maxAbs = std::max(maxAbs, r);
        maxRel = std::max(maxRel, r / d);
        maxSqrt = std::max(maxSqrt, r / std::sqrt(d));
        sum2 += r * r;
    }
    result.maxAbsolute = maxAbs;
    result.maxRelative = maxRel;
    result.maxSqrtScaled = maxSqrt;
    result.rms = std::sqrt(sum2 / double(p.rows()));
}

// ---- least squares ------------------------------------------------------------------------

/// The equilibrated normal equations N' y = b' with N' = S N S, b' = S b, x = S y, where
/// S = diag(N)^(-1/2) (1 for a column with an empty diagonal).
class NormalEquations
{
public:
    NormalEquations(const FitProblem& p, double ridge)
    {
        const Eigen::Index n = Eigen::Index(p.columns);
        const size_t m = p.rows();
        // Rows filling over an eighth of the columns make N essentially dense.
        mDense = p.columns <= 64 || 8.0 * double(p.column.size()) > double(m) * double(n);
        mB = Vector::Zero(n);
        auto rowW = [&](size_t k) { return p.rowWeight.empty() ? 1.0 : p.rowWeight[k]; };
        if (mDense) {
            // N += B^T B over blocks B of rows scaled by sqrt(w): a rank-k update runs at matrix
            // product speed, and the blocks bound the memory.
            constexpr size_t kBlock = 256;
            mN = Eigen::MatrixXd::Zero(n, n);
            Eigen::MatrixXd block(kBlock, n);
            Vector blockY(kBlock);
            for (size_t k0 = 0; k0 < m; k0 += kBlock) {
                const size_t count = std::min(kBlock, m - k0);
                block.topRows(Eigen::Index(count)).setZero();
                for (size_t r = 0; r < count; ++r) {
                    const size_t k = k0 + r;
                    const double sw = std::sqrt(rowW(k));
                    for (size_t i = p.rowStart[k]; i < p.rowStart[k + 1]; ++i) {
                        block(Eigen::Index(r), Eigen::Index(p.column[i])) += sw * p.weight[i];
                    }
                    blockY[Eigen::Index(r)] = sw * p.target[k];
                }
                const auto rows = block.topRows(Eigen::Index(count));
                mN.selfadjointView<Eigen::Lower>().rankUpdate(rows.transpose());
                mB.noalias() += rows.transpose() * blockY.head(Eigen::Index(count));
            }
            mN = mN.selfadjointView<Eigen::Lower>();
            mN.diagonal().array() += ridge;
            mScale = Vector::Ones(n);
            for (Eigen::Index j = 0; j < n; ++j) {
                if (mN(j, j) > 0.0) mScale[j] = 1.0 / std::sqrt(mN(j, j));
            }
            mN = mScale.asDiagonal() * mN * mScale.asDiagonal();
        } else {
            std::vector<Eigen::Triplet<double>> entries;
            entries.reserve(p.column.size());
            for (size_t k = 0; k < m; ++k) {
                const double w = rowW(k), sw = std::sqrt(w);
                for (size_t i = p.rowStart[k]; i < p.rowStart[k + 1]; ++i) {
                    entries.emplace_back(int(k), int(p.column[i]), sw * p.weight[i]);
                    mB[p.column[i]] += w * p.weight[i] * p.target[k];
                }
            }
            // Repeated columns within a row add up, as in the row's value.
            SparseMatrix B(Eigen::Index(m), n);
            B.setFromTriplets(entries.begin(), entries.end());
            mSparseN = SparseMatrix(B.transpose()) * B;
            if (ridge > 0.0) {
                SparseMatrix I(n, n);
                I.setIdentity();
                mSparseN += ridge * I;
            }
            mScale = Vector::Ones(n);
            for (Eigen::Index j = 0; j < n; ++j) {
                for (SparseMatrix::InnerIterator it(mSparseN, j); it; ++it) {
                    if (it.row() == j && it.value() > 0.0) mScale[j] = 1.0 / std::sqrt(it.value());
                }
            }
            for (Eigen::Index j = 0; j < n; ++j) {
                for (SparseMatrix::InnerIterator it(mSparseN, j); it; ++it) {
                    it.valueRef() *= mScale[it.row()] * mScale[j];
                }
            }
        }
        mB = mScale.cwiseProduct(mB);
    }

    Eigen::Index size() const { return mB.size(); }
    const Vector& scale() const { return mScale; }
    const Vector& rhs() const { return mB; }
    /// b' - N' y: minus the gradient of (1/2) y^T N' y - b'^T y.
    Vector gradient(const Vector& y) const
    {
        if (mDense) return mB - mN * y;
        return mB - mSparseN * y;
    }

    /// @brief The minimiser over the @a active columns (all when @a all), the others held at 0.
    /// @a rankDeficient: whether the reduced matrix was singular (minimum-norm solution).
    Vector solve(const std::vector<Eigen::Index>& active, bool all, bool& rankDeficient) const
    {
        const Eigen::Index n = size(), na = all ? n : Eigen::Index(active.size());
        Vector rhs(na);
        for (Eigen::Index i = 0; i < na; ++i) rhs[i] = mB[all ? i : active[size_t(i)]];
        Vector z;
        rankDeficient = false;
        if (mDense) {
            Eigen::MatrixXd sub;
            if (all) sub = mN;
            else sub = mN(active, active);
            Eigen::LDLT<Eigen::MatrixXd> ldlt(sub);
            if (ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > kRankTolerance) {
                z = ldlt.solve(rhs);
            } else {
                z = minimumNorm(sub, rhs);
                rankDeficient = true;
            }
        } else {
            SparseMatrix sub;
            if (all) {
                sub = mSparseN;
            } else {
                std::vector<int> position(size_t(n), -1);
                for (size_t i = 0; i < active.size(); ++i) position[size_t(active[i])] = int(i);
                std::vector<Eigen::Triplet<double>> entries;
                for (size_t i = 0; i < active.size(); ++i) {
                    for (SparseMatrix::InnerIterator it(mSparseN, active[i]); it; ++it) {
                        const int row = position[size_t(it.row())];
                        if (row >= 0) entries.emplace_back(row, int(i), it.value());
                    }
                }
                sub.resize(na, na);
                sub.setFromTriplets(entries.begin(), entries.end());
            }
            Eigen::SimplicialLDLT<SparseMatrix> ldlt(sub);
            if (ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > kRankTolerance) {
                z = ldlt.solve(rhs);
            } else {
                z = minimumNorm(Eigen::MatrixXd(sub), rhs);
                rankDeficient = true;
            }
        }
        if (all) return z;
        Vector full = Vector::Zero(n);
        for (Eigen::Index i = 0; i < na; ++i) full[active[size_t(i)]] = z[i];
        return full;
    }

private:
    static Vector minimumNorm(const Eigen::MatrixXd& matrix, const Vector& rhs)
    {
        Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod;
        cod.setThreshold(kRankTolerance);
        cod.compute(matrix);
        return cod.solve(rhs);
    }

    bool mDense = false;
    Eigen::MatrixXd mN;
    SparseMatrix mSparseN;
    Vector mB, mScale;
};

/// @brief Lawson & Hanson's active-set method for min (1/2) y^T N' y - b'^T y subject to y >= 0,
/// starting from the positive part of the unconstrained minimiser @a start.
Vector
nonNegativeLeastSquares(const NormalEquations& ne, const Vector& start, bool& rankDeficient)
{
    const Eigen::Index n = ne.size();
    const double scale = ne.rhs().cwiseAbs().maxCoeff();
    if (!(scale > 0.0)) return Vector::Zero(n); // b' = 0: y = 0 is optimal
    // Stationarity tolerance on the gradient, relative to b' (the gradient at y = 0).
    const double tolerance = 1e-10 * scale;
    std::vector<char> passive(size_t(n), 0), blocked(size_t(n), 0);
    Vector y = Vector::Zero(n);
    for (Eigen::Index j = 0; j < n; ++j) {
        if (start[j] > 0.0) passive[size_t(j)] = 1, y[j] = start[j];
    }
    // Each outer step frees one variable; variables return to the bound at most as often, so a
    // few times n steps means the iteration is cycling on rounding errors.
    const long maxSteps = 3 * long(n) + 100;
    std::vector<Eigen::Index> active;
    Eigen::Index added = -1; // the variable freed by the previous step
    for (long step = 0; step < maxSteps; ++step) {
        // Move towards the minimiser on the passive set, dropping variables that reach 0 on the
        // way (each pass drops at least one).
        bool rejected = false;
        for (bool first = true;; first = false) {
            active.clear();
            for (Eigen::Index j = 0; j < n; ++j) {
                if (passive[size_t(j)]) active.push_back(j);
            }
            if (active.empty()) break;
            const Vector z = ne.solve(active, false, rankDeficient);
            double alpha = 1.0;
            Eigen::Index hit = -1;
            for (Eigen::Index j : active) {
                if (z[j] <= 0.0) {
                    const double a = y[j] / (y[j] - z[j]);
                    if (a < alpha || hit < 0) alpha = a, hit = j;
                }
            }
            if (hit < 0) {
                y = z;
                break;
            }
            // The variable just freed cannot move inward (z_j <= 0 although its gradient said
            // it should: rounding).
            if (first && alpha <= 0.0 && hit == added) rejected = true;
            for (Eigen::Index j : active) {
                y[j] += alpha * (z[j] - y[j]);
                if (j == hit || y[j] <= 0.0) y[j] = 0.0, passive[size_t(j)] = 0;
            }
        }
        // A rejected variable stays out until another one is freed with progress (the
        // objective then decreased, and its gradient may have changed).
        if (rejected) blocked[size_t(added)] = 1;
        else std::fill(blocked.begin(), blocked.end(), 0);
        const Vector g = ne.gradient(y);
        Eigen::Index best = -1;
        for (Eigen::Index j = 0; j < n; ++j) {
            if (passive[size_t(j)] || blocked[size_t(j)]) continue;
            if (best < 0 || g[j] > g[best]) best = j;
        }
        if (best < 0 || g[best] <= tolerance) return y;
        passive[size_t(best)] = 1;
        added = best;
    }
    OPENVDB_THROW(openvdb::RuntimeError, "fit: non-negative least squares did not converge in "
        << maxSteps << " steps");
}

std::vector<double>
leastSquares(const FitProblem& p, const FitOptions& options, bool& rankDeficient)
{
    NormalEquations ne(p, options.ridge);
    Vector y = ne.solve({}, true, rankDeficient);
    if (options.nonNegative && y.minCoeff() < 0.0) {
        y = nonNegativeLeastSquares(ne, y, rankDeficient);
    }
    const Vector x = ne.scale().cwiseProduct(y);
    return std::vector<double>(x.data(), x.data() + x.size());
}
} // namespace

FitResult
fitControlValues(const FitProblem& problem, const FitOptions& options)
{
    const auto start = Clock::now();
    validate(problem);
    validateFloor(options.valueFloor);
    if (!(options.ridge >= 0.0) || !std::isfinite(options.ridge)) {
        OPENVDB_THROW(openvdb::ValueError, "fit: ridge " << options.ridge
            << " (must be finite and >= 0)");
    }
    FitResult result;
    switch (options.norm) {
        case FitNorm::LeastSquares:
            result.x = leastSquares(problem, options, result.rankDeficient);
            break;
        case FitNorm::MaxAbsolute:
        case FitNorm::MaxRelative:
        case FitNorm::MaxSqrtScaled:
            result.x = fit::maxNorm(problem, options, result.lpIterations);
            break;
        default: OPENVDB_THROW(openvdb::ValueError, "fit: unknown norm " << int(options.norm));
    }
    fillStatistics(problem, result.x, options.valueFloor, result);
    result.seconds = secondsSince(start);
    return result;
}

FitResult
residuals(const FitProblem& problem, const std::vector<double>& x, double valueFloor)
{
    const auto start = Clock::now();
    validate(problem);
    validateFloor(valueFloor);
    if (x.size() != problem.columns) {
        OPENVDB_THROW(openvdb::ValueError, "fit residuals: " << x.size() << " values for "
            << problem.columns << " columns");
    }
    for (size_t j = 0; j < x.size(); ++j) {
        if (!std::isfinite(x[j])) {
            OPENVDB_THROW(openvdb::ValueError, "fit residuals: x[" << j << "] is " << x[j]);
        }
    }
    FitResult result;
    result.x = x;
    fillStatistics(problem, x, valueFloor, result);
    result.seconds = secondsSince(start);
    return result;
}

} // namespace vdbrad
