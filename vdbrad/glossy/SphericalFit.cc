// SphericalFit: least squares through the normal equations (Eigen), the max norms as linear
// programs solved by GLPK's simplex method.
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
//
// The max norms minimise t subject to -t <= s_k (A_k X - Y_k) <= t (two LP rows per sample),
// with s_k = 1, 1 / |Y_k| or 1 / sqrt(|Y_k|) after the value floor, targets divided by max |Y|
// so that every |s_k Y_k| <= 1 whatever the units. An optimum rests on about columns + 1
// samples, so the LP is solved by row generation: GLPK's dual simplex on a strided subset of
// ~2,000 samples, then the samples the solution violates join (the worst first) and the dual
// simplex continues from its basis, which stays dual feasible. The LPs stay a few thousand rows:
// 50,000 x 642 interpolation rows take ~0.6 s per norm where the whole LP took 5-9 s, and
// 40,000 dense rows of 289 harmonics 17-28 s (~600 MB) where the whole LP (23M nonzeros,
// ~5 GB) was impractical. GLPK's presolver is not used: it discards the basis that each round
// continues from, and on dense harmonic rows it returned wrong "optimal" solutions or spun for
// minutes; it remains in the last fallback.
//
// A subset's optimum bounds the full one from below, so a solution that satisfies every sample
// (to 1e-9 of t) is the full optimum: that is checked on all samples rather than trusted to
// GLPK's tolerances, which at their defaults let solutions exceed their t by up to 0.5% and stop
// ~1e-8 above the optimum (hence tol_bnd 1e-9, tightened when GLPK's own rows fail the check,
// and a last pass with tol_dj 1e-11). Should an attempt fail or not pass the check, the LP is
// solved again with the primal simplex, then with GLPK's own scaling and presolver; the best
// solution found is returned either way, and the reported statistics are always recomputed.
#include "vdbrad/glossy/SphericalFit.h"

#include <openvdb/Exceptions.h>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <glpk.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <limits>
#include <memory>

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

double
maxAbsTarget(const FitProblem& p)
{
    double maxY = 0.0;
    for (double y : p.target) maxY = std::max(maxY, std::abs(y));
    return maxY;
}

/// The relative measures' denominator floor; 1 when every target is 0 (any fit is then measured
/// absolutely, and X = 0 is exact for all of them).
double
denominatorFloor(const FitProblem& p, double valueFloor)
{
    const double maxY = maxAbsTarget(p);
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

// ---- max norms (GLPK) ---------------------------------------------------------------------

struct ProblemDeleter
{
    void operator()(glp_prob* lp) const { glp_delete_prob(lp); }
};

/// GLPK's terminal output off for the scope (glp_scale_prob and the presolver print otherwise).
/// The setting, like all of GLPK's state, is per thread in a reentrant build (Debian's 5.0 is),
/// so fits may run in parallel threads.
class TerminalSilence
{
public:
    TerminalSilence() : mPrevious(glp_term_out(GLP_OFF)) {}
    ~TerminalSilence() { glp_term_out(mPrevious); }
    TerminalSilence(const TerminalSilence&) = delete;
    TerminalSilence& operator=(const TerminalSilence&) = delete;

private:
    int mPrevious;
};

const char*
simplexError(int code)
{
    switch (code) {
        case 0: return "no error";
        case GLP_EBADB: return "invalid initial basis";
        case GLP_ESING: return "singular basis matrix";
        case GLP_ECOND: return "ill-conditioned basis matrix";
        case GLP_EBOUND: return "incorrect bounds";
        case GLP_EFAIL: return "solver failure";
        case GLP_EOBJLL: return "objective lower limit reached";
        case GLP_EOBJUL: return "objective upper limit reached";
        case GLP_EITLIM: return "iteration limit exceeded";
        case GLP_ETMLIM: return "time limit exceeded";
        case GLP_ENOPFS: return "no primal feasible solution";
        case GLP_ENODFS: return "no dual feasible solution";
        default: return "unknown error";
    }
}

const char*
statusName(int status)
{
    switch (status) {
        case GLP_OPT: return "optimal";
        case GLP_FEAS: return "feasible";
        case GLP_INFEAS: return "infeasible";
        case GLP_NOFEAS: return "no feasible solution";
        case GLP_UNBND: return "unbounded";
        default: return "undefined";
    }
}

/// The LP of a max norm, min t subject to -t <= s_k (A_k X - y_k) <= t, in units of max |Y|
/// (y = Y / max |Y|), with each row's repeated columns merged (GLPK rejects duplicates).
struct MaxNormLp
{
    int columns = 0;               // unknowns; t is GLPK's column columns + 1
    std::vector<size_t> rowStart;  // entries of row k: rowStart[k] .. rowStart[k + 1]
    std::vector<int> column;       // 0-based
    std::vector<double> value;     // s_k A_kj
    std::vector<double> rhs;       // s_k y_k
    std::vector<char> used;        // whether some row depends on the unknown
    bool nonNegative = false;

    size_t rows() const { return rhs.size(); }
};

MaxNormLp
buildMaxNormLp(const FitProblem& p, const FitOptions& options, double unit)
{
    MaxNormLp lp;
    lp.columns = int(p.columns);
    lp.nonNegative = options.nonNegative;
    lp.used.assign(p.columns, 0);
    lp.rowStart.reserve(p.rows() + 1);
    lp.rowStart.push_back(0);
    lp.rhs.reserve(p.rows());
    lp.column.reserve(p.column.size());
    lp.value.reserve(p.column.size());
    std::vector<double> sum(p.columns, 0.0);
    std::vector<size_t> seenInRow(p.columns, SIZE_MAX);
    std::vector<uint32_t> rowColumns;
    for (size_t k = 0; k < p.rows(); ++k) {
        rowColumns.clear();
        for (size_t i = p.rowStart[k]; i < p.rowStart[k + 1]; ++i) {
            const uint32_t j = p.column[i];
            if (seenInRow[j] != k) seenInRow[j] = k, rowColumns.push_back(j);
            sum[j] += p.weight[i];
        }
        const double y = p.target[k] / unit;
        double s = 1.0;
        if (options.norm == FitNorm::MaxRelative) {
            s = 1.0 / std::max(std::abs(y), options.valueFloor);
        } else if (options.norm == FitNorm::MaxSqrtScaled) {
            s = 1.0 / std::sqrt(std::max(std::abs(y), options.valueFloor));
        }
        for (uint32_t j : rowColumns) {
            // Exact zeros (cancelled repeats) are dropped.
            if (sum[j] != 0.0) {
                lp.column.push_back(int(j));
                lp.value.push_back(s * sum[j]);
                lp.used[j] = 1;
            }
            sum[j] = 0.0;
        }
        lp.rowStart.push_back(lp.column.size());
        lp.rhs.push_back(s * y);
    }
    return lp;
}

/// How GLPK is set up for one attempt at the LP (see maxNorm).
enum class LpSetup { ColumnScaled, ColumnScaledPrimal, GlpkScaled };

struct LpSolution
{
    bool solved = false;     // the simplex reported an optimum
    bool certified = false;  // ... and x satisfies every row (so it is the optimum of them all)
    int code = 0, status = GLP_UNDEF, iterations = 0;
    double objective = 0.0;  // max_k |s_k (A_k x - y_k)|, recomputed over every row
    std::vector<double> x;
};

/// @brief One attempt at the LP by row generation (see the file comment): the simplex solves
/// it on a subset of the samples, the samples its solution violates join, and the dual simplex
/// continues from the previous basis, until no sample is violated (certified).
LpSolution
solveMaxNormLp(const MaxNormLp& lp, LpSetup setup)
{
    const size_t m = lp.rows(), n = size_t(lp.columns);
    const int tColumn = lp.columns + 1;
    // Unknowns in units that make each column's largest coefficient 1 (but for GlpkScaled): the
    // interpolation weights are O(1), but the relative measures multiply rows by up to 1/floor.
    // Rows are left alone: a row's violation is then in units of t, which GLPK's tolerances
    // bound uniformly (every |rhs| <= 1).
    std::vector<double> scale(n, 1.0);
    if (setup != LpSetup::GlpkScaled) {
        std::vector<double> largest(n, 0.0);
        for (size_t i = 0; i < lp.column.size(); ++i) {
            double& l = largest[size_t(lp.column[i])];
            l = std::max(l, std::abs(lp.value[i]));
        }
        for (size_t j = 0; j < n; ++j) {
            if (largest[j] > 0.0) scale[j] = 1.0 / largest[j];
        }
    }

    std::unique_ptr<glp_prob, ProblemDeleter> prob(glp_create_prob());
    glp_prob* P = prob.get();
    glp_set_obj_dir(P, GLP_MIN);
    glp_add_cols(P, tColumn);
    glp_set_col_bnds(P, tColumn, GLP_LO, 0.0, 0.0);
    glp_set_obj_coef(P, tColumn, 1.0);
    for (size_t j = 0; j < n; ++j) {
        // An unknown no sample touches is arbitrary: pin it at 0.
        const int type = !lp.used[j] ? GLP_FX : lp.nonNegative ? GLP_LO : GLP_FR;
        glp_set_col_bnds(P, int(j) + 1, type, 0.0, 0.0);
    }
    std::vector<int> index(n + 2);
    std::vector<double> coefficient(n + 2);
    const auto addRow = [&](size_t k) {
        // s_k (A_k X - y_k) - t <= 0 and s_k (A_k X - y_k) + t >= 0.
        const int upper = glp_add_rows(P, 2);
        int count = 0;
        for (size_t i = lp.rowStart[k]; i < lp.rowStart[k + 1]; ++i) {
            const size_t j = size_t(lp.column[i]);
            ++count;
            index[size_t(count)] = int(j) + 1;
            coefficient[size_t(count)] = lp.value[i] * scale[j];
        }
        index[size_t(count) + 1] = tColumn;
        for (int row : {upper, upper + 1}) {
            coefficient[size_t(count) + 1] = row == upper ? -1.0 : 1.0;
            glp_set_mat_row(P, row, count + 1, index.data(), coefficient.data());
        }
        glp_set_row_bnds(P, upper, GLP_UP, 0.0, lp.rhs[k]);
        glp_set_row_bnds(P, upper + 1, GLP_LO, lp.rhs[k], 0.0);
    };
    // Start from an evenly strided subset, a few times the rows an optimum rests on.
    const size_t batch = std::max<size_t>(1000, 2 * (n + 1));
    const size_t initial = std::min(m, 2 * batch);
    std::vector<char> inLp(m, 0);
    for (size_t i = 0; i < initial; ++i) {
        const size_t k = size_t(double(i) * double(m) / double(initial));
        if (!inLp[k]) inLp[k] = 1, addRow(k);
    }

    glp_smcp parm;
    glp_init_smcp(&parm);
    parm.msg_lev = GLP_MSG_OFF;
    // The slack basis is dual feasible (t at its bound 0 with cost 1, X free with cost 0), and
    // stays so as rows join: the dual simplex needs no phase 1. It took 10-20x fewer iterations
    // than the primal on these problems.
    parm.meth = setup == LpSetup::ColumnScaledPrimal ? GLP_PRIMAL : GLP_DUALP;
    // A stall (GLPK's presolver and scaling once spun for minutes on dense harmonic rows) ends
    // the attempt; the LPs here need a few thousand iterations.
    parm.it_lim = int(std::min<size_t>(INT_MAX, std::max<size_t>(100000, 200 * (n + 1))));
    // Harris' ratio test lets basic variables stray past their bounds by up to tol_bnd: the
    // default 1e-7 left visible excess (0.5% of a relative error, once unscaled).
    parm.tol_bnd = 1e-9;
    LpSolution solution;
    solution.x.assign(n, 0.0);
    std::vector<double> residual(m);
    std::vector<size_t> violated;
    // GLPK's optimality test allows reduced costs of the wrong sign up to tol_dj (1e-7), which
    // left objectives up to ~1e-8 (relative) above the optimum: once certified, the solution
    // is polished from its basis with a tighter tol_dj, and kept unless that does worse.
    LpSolution previous;
    bool polishing = false;
    const auto finish = [&](LpSolution& s) -> LpSolution& {
        if (!polishing) return s;
        const bool better = s.solved && s.certified && s.objective <= previous.objective;
        LpSolution& kept = better ? s : previous;
        kept.iterations = glp_get_it_cnt(P);
        return kept;
    };
    for (int round = 0;; ++round) {
        if (setup == LpSetup::GlpkScaled) {
            glp_scale_prob(P, GLP_SF_AUTO);
            // The presolver starts afresh, so only the first round uses it.
            parm.presolve = round == 0 ? GLP_ON : GLP_OFF;
        }
        solution.certified = false;
        // A fresh factorization of the basis: the one GLPK keeps between calls carries its
        // updates' rounding (2e-10 on a row of a 164-row LP, where t needed 1e-11).
        if (round > 0) glp_factorize(P);
        solution.code = glp_simplex(P, &parm);
        solution.iterations = glp_get_it_cnt(P);
        solution.status = glp_get_status(P);
        solution.solved = solution.code == 0 && solution.status == GLP_OPT;
        if (!solution.solved) return std::move(finish(solution));
        const double t = glp_get_col_prim(P, tColumn);
        for (size_t j = 0; j < n; ++j) {
            solution.x[j] = scale[j] * glp_get_col_prim(P, int(j) + 1);
            // The simplex honours bounds only to its tolerance.
            if (lp.nonNegative) solution.x[j] = std::max(solution.x[j], 0.0);
        }
        // Rows violated by more than rounding: 1e-9 of t, or 1e-12 of the row's terms (dense
        // rows of harmonics sum hundreds of terms of either sign).
        solution.objective = 0.0;
        violated.clear();
        double excessInLp = 0.0;
        for (size_t k = 0; k < m; ++k) {
            double v = -lp.rhs[k], magnitude = std::abs(lp.rhs[k]);
            for (size_t i = lp.rowStart[k]; i < lp.rowStart[k + 1]; ++i) {
                const double term = lp.value[i] * solution.x[size_t(lp.column[i])];
                v += term;
                magnitude += std::abs(term);
            }
            residual[k] = std::abs(v);
            solution.objective = std::max(solution.objective, residual[k]);
            const double excess = residual[k] - t * (1.0 + 1e-9) - 1e-12 * magnitude;
            if (excess <= 0.0) continue;
            if (inLp[k]) excessInLp = std::max(excessInLp, excess);
            else violated.push_back(k);
        }
        // GLPK's own rows may be violated within its tolerance (tol_bnd, relative to
        // 1 + |rhs| <= 2), but by more the simplex is not to be trusted on this problem (GLPK's
        // presolver once returned t = 0 for a solution off by 8): give up the attempt.
        if (excessInLp > 1e-6) return std::move(finish(solution));
        if (violated.empty()) {
            if (excessInLp > 0.0 && parm.tol_bnd > 1e-11) {
                // Loose only: pivot on with a tighter tolerance.
                parm.tol_bnd = 1e-11;
                continue;
            }
            // Every row holds to rounding: the optimum of them all. Where a fit is nearly exact
            // (t ~ 1e-5 on dense harmonic rows) rounding in GLPK's basis solves leaves ~1e-11
            // on its own rows, at the resolution of the data (|rhs| <= 1): accepted too.
            solution.certified = excessInLp <= 1e-9;
            if (polishing || !solution.certified) return std::move(finish(solution));
            previous = solution;
            polishing = true;
            parm.tol_dj = 1e-11;
            continue;
        }
        // The worst violations first: they are the likeliest rows of the optimum.
        if (violated.size() > batch) {
            std::nth_element(violated.begin(), violated.begin() + long(batch), violated.end(),
                [&](size_t a, size_t b) { return residual[a] > residual[b]; });
            violated.resize(batch);
        }
        for (size_t k : violated) inLp[k] = 1, addRow(k);
    }
}

/// @brief The max-norm fit: GLPK's simplex under up to three setups, until one's solution is
/// certified (satisfies every row to the tolerance); otherwise the best one found.
std::vector<double>
maxNorm(const FitProblem& p, const FitOptions& options, int& iterations)
{
    const size_t m = p.rows();
    if (2.0 * double(m) >= double(INT_MAX)) {
        OPENVDB_THROW(openvdb::ValueError, "fit: " << m << " rows are too many for the LP solver");
    }
    // Targets in units of max |Y|, so that the LP's numbers are O(1); X scales with them.
    const double maxY = maxAbsTarget(p), unit = maxY > 0.0 ? maxY : 1.0;
    const MaxNormLp lp = buildMaxNormLp(p, options, unit);

    TerminalSilence silence;
    LpSolution best, last;
    iterations = 0;
    for (LpSetup setup :
        {LpSetup::ColumnScaled, LpSetup::ColumnScaledPrimal, LpSetup::GlpkScaled})
    {
        last = solveMaxNormLp(lp, setup);
        iterations += last.iterations;
        if (!last.solved) continue;
        const bool certified = last.certified;
        if (!best.solved || last.objective < best.objective) best = std::move(last);
        if (certified) break;
    }
    if (!best.solved) {
        OPENVDB_THROW(openvdb::RuntimeError, "fit: the LP solver failed ("
            << simplexError(last.code) << ", solution " << statusName(last.status) << ") on "
            << m << " rows x " << p.columns << " columns");
    }
    for (double& v : best.x) v *= unit;
    return std::move(best.x);
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
            result.x = maxNorm(problem, options, result.lpIterations);
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
