// MaxNormFit: the max norms of SphericalFit (SphericalFit.h) as linear programs solved by GLPK's
// simplex method; the least squares are in SphericalFit.cc.
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
#include "vdbrad/glossy/MaxNormFit.h"

#include <openvdb/Exceptions.h>

#include <glpk.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace vdbrad {
namespace fit {

namespace {

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

/// @brief The unknowns' units for @a setup: each column's largest coefficient becomes 1 (but for
/// GlpkScaled, where GLPK scales the problem itself).
std::vector<double>
columnScale(const MaxNormLp& lp, LpSetup setup)
{
    const size_t n = size_t(lp.columns);
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
    return scale;
}

/// GLPK's problem for one attempt: min t over the scaled unknowns (columns 1 .. columns) and t
/// (column columns + 1), with the rows of the samples added so far.
class GlpkMaxNormLp
{
public:
    GlpkMaxNormLp(const MaxNormLp& lp, std::vector<double> scale)
        : mLp(lp)
        , mScale(std::move(scale))
        , mProb(glp_create_prob())
        , mIndex(size_t(lp.columns) + 2)
        , mCoefficient(size_t(lp.columns) + 2)
    {
        glp_prob* P = mProb.get();
        glp_set_obj_dir(P, GLP_MIN);
        glp_add_cols(P, tColumn());
        glp_set_col_bnds(P, tColumn(), GLP_LO, 0.0, 0.0);
        glp_set_obj_coef(P, tColumn(), 1.0);
        for (size_t j = 0; j < size_t(lp.columns); ++j) {
            // An unknown no sample touches is arbitrary: pin it at 0.
            const int type = !lp.used[j] ? GLP_FX : lp.nonNegative ? GLP_LO : GLP_FR;
            glp_set_col_bnds(P, int(j) + 1, type, 0.0, 0.0);
        }
    }

    glp_prob* get() const { return mProb.get(); }
    int tColumn() const { return mLp.columns + 1; }

    /// Adds sample @a k's two rows.
    void addSample(size_t k)
    {
        glp_prob* P = mProb.get();
        // s_k (A_k X - y_k) - t <= 0 and s_k (A_k X - y_k) + t >= 0.
        const int upper = glp_add_rows(P, 2);
        int count = 0;
        for (size_t i = mLp.rowStart[k]; i < mLp.rowStart[k + 1]; ++i) {
            const size_t j = size_t(mLp.column[i]);
            ++count;
            mIndex[size_t(count)] = int(j) + 1;
            mCoefficient[size_t(count)] = mLp.value[i] * mScale[j];
        }
        mIndex[size_t(count) + 1] = tColumn();
        for (int row : {upper, upper + 1}) {
            mCoefficient[size_t(count) + 1] = row == upper ? -1.0 : 1.0;
            glp_set_mat_row(P, row, count + 1, mIndex.data(), mCoefficient.data());
        }
        glp_set_row_bnds(P, upper, GLP_UP, 0.0, mLp.rhs[k]);
        glp_set_row_bnds(P, upper + 1, GLP_LO, mLp.rhs[k], 0.0);
    }

    /// The simplex's X, in the LP's units (unscaled), into @a x.
    void readUnknowns(std::vector<double>& x) const
    {
        for (size_t j = 0; j < x.size(); ++j) {
            x[j] = mScale[j] * glp_get_col_prim(mProb.get(), int(j) + 1);
            // The simplex honours bounds only to its tolerance.
            if (mLp.nonNegative) x[j] = std::max(x[j], 0.0);
        }
    }

private:
    const MaxNormLp& mLp;
    const std::vector<double> mScale;
    std::unique_ptr<glp_prob, ProblemDeleter> mProb;
    std::vector<int> mIndex;            // a row's columns and coefficients, 1-based for GLPK
    std::vector<double> mCoefficient;
};

/// The simplex's settings for @a setup on an LP of @a n unknowns.
glp_smcp
simplexParameters(LpSetup setup, size_t n)
{
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
    return parm;
}

/// @brief Measures @a solution.x on every sample against the LP's @a t: sets its objective and
/// each sample's @a residual, lists in @a violated the samples outside the LP (@a inLp) that it
/// violates, and returns the largest excess over t of the samples in the LP (0: none).
double
checkSamples(const MaxNormLp& lp, const std::vector<char>& inLp, double t, LpSolution& solution,
    std::vector<double>& residual, std::vector<size_t>& violated)
{
    // Rows violated by more than rounding: 1e-9 of t, or 1e-12 of the row's terms (dense
    // rows of harmonics sum hundreds of terms of either sign).
    solution.objective = 0.0;
    violated.clear();
    double excessInLp = 0.0;
    for (size_t k = 0; k < lp.rows(); ++k) {
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
    return excessInLp;
}

/// @brief One attempt at the LP by row generation (see the file comment): the simplex solves
/// it on a subset of the samples, the samples its solution violates join, and the dual simplex
/// continues from the previous basis, until no sample is violated (certified).
LpSolution
solveMaxNormLp(const MaxNormLp& lp, LpSetup setup)
{
    const size_t m = lp.rows(), n = size_t(lp.columns);
    GlpkMaxNormLp glpk(lp, columnScale(lp, setup));
    glp_prob* P = glpk.get();
    // Start from an evenly strided subset, a few times the rows an optimum rests on.
    const size_t batch = std::max<size_t>(1000, 2 * (n + 1));
    const size_t initial = std::min(m, 2 * batch);
    std::vector<char> inLp(m, 0);
    for (size_t i = 0; i < initial; ++i) {
        const size_t k = size_t(double(i) * double(m) / double(initial));
        if (!inLp[k]) inLp[k] = 1, glpk.addSample(k);
    }

    glp_smcp parm = simplexParameters(setup, n);
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
        const double t = glp_get_col_prim(P, glpk.tColumn());
        glpk.readUnknowns(solution.x);
        const double excessInLp = checkSamples(lp, inLp, t, solution, residual, violated);
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
        for (size_t k : violated) inLp[k] = 1, glpk.addSample(k);
    }
}

} // namespace

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

} // namespace fit
} // namespace vdbrad
