// SphericalFit: the values X at a representation's unknowns (control points on the sphere,
// spherical-harmonic coefficients) that best reproduce sampled values of a function, under the
// four error measures the thesis compares (Chatelier & Malgouyres, ch. 5, §5.2).
//
// A glossy BRDF or a phase function is stored as values at control points of an icosahedral
// grid; a direction's value is interpolated from the three corners of its triangle, i.e. a sparse
// row of weights times X (a dense row for harmonics). Given sampled directions (rows A_k) and the
// true values Y_k, the fit chooses X so that A X ~ Y:
//
//     least squares        minimise sum_k w_k (A_k X - Y_k)^2           (the thesis' final choice)
//     (5.1) max absolute   minimise max_k |A_k X - Y_k|
//     (5.2) max relative   minimise max_k |A_k X - Y_k| / |Y_k|
//     (5.3) sqrt-scaled    minimise max_k |A_k X - Y_k| / sqrt(|Y_k|)
//
// The three max norms are linear programs (min t subject to -t <= s_k (A_k X - Y_k) <= t). The
// relative measures need a denominator for samples whose value is 0 (a BRDF below the horizon,
// a lobe's far tail): |Y_k| is replaced by max(|Y_k|, valueFloor * max_j |Y_j|) everywhere, in
// the LPs and in the reported statistics alike: values under a thousandth of the peak (the
// default floor) are measured against that thousandth, so a zero sample requires
// |A_k X| <= 1e-3 t max|Y|. A tiny floor (1e-6) is closer to the thesis' "over Y_k > 0" but makes
// the zero samples dominate: the fit must all but vanish there, the LP turns near-degenerate
// (a clipped lobe on 289 harmonics took 4.5 minutes instead of 25 s) and the relative error
// elsewhere approaches 1.
//
// Non-negative fits (radiance, a BRDF) bound X >= 0: simple bounds in the LPs, an active-set
// method (Lawson & Hanson) for least squares; the result is the exact constrained optimum, not a
// clamped unconstrained one.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace vdbrad {

/// @brief A linear fitting problem: row k of the design matrix A (compressed rows: entries
/// rowStart[k] .. rowStart[k+1]) and its target Y_k. Rows may be sparse (interpolation from
/// control points) or dense (spherical harmonics); repeated columns within a row add up.
struct FitProblem
{
    /// Unknowns (control points or harmonic coefficients).
    size_t columns = 0;
    /// rowStart.size() == rows() + 1 once a row is added (addRow keeps it so).
    std::vector<size_t> rowStart;
    std::vector<uint32_t> column;
    std::vector<double> weight;
    /// Y, one per row.
    std::vector<double> target;
    /// Least-squares weights w_k >= 0, one per row; empty: all 1. The max norms ignore them.
    std::vector<double> rowWeight;

    /// Appends the row sum_i w[i] X[cols[i]] ~ y.
    void addRow(const uint32_t* cols, const double* w, size_t count, double y,
        double leastSquaresWeight = 1.0);
    /// @throw openvdb::ValueError if @a cols and @a w differ in size
    void addRow(const std::vector<uint32_t>& cols, const std::vector<double>& w, double y,
        double leastSquaresWeight = 1.0);
    /// Appends a dense row over all @a columns unknowns (w has @c columns entries).
    void addDenseRow(const double* w, double y, double leastSquaresWeight = 1.0);
    size_t rows() const { return target.size(); }
};

enum class FitNorm { LeastSquares, MaxAbsolute, MaxRelative, MaxSqrtScaled };

struct FitOptions
{
    FitNorm norm = FitNorm::LeastSquares;
    /// Constrain X >= 0 (see the file comment).
    bool nonNegative = false;
    /// @brief Least squares only: adds ridge * |X|^2 to the objective, which pins unknowns the
    /// samples do not determine (a control point no sample touches) at 0. Without it such
    /// unknowns get the minimum-norm value (0 for an untouched one).
    double ridge = 0.0;
    /// Denominator floor of the relative measures, as a fraction of max |Y| (in (0, 1]).
    double valueFloor = 1e-3;
};

struct FitResult
{
    std::vector<double> x;
    /// Residual statistics over all rows (always filled in, whatever the norm): the maxima of
    /// |r_k|, |r_k| / max(|Y_k|, floor), |r_k| / sqrt(max(|Y_k|, floor)), and the unweighted
    /// root mean square of r_k, where r_k = A_k X - Y_k.
    double maxAbsolute = 0.0, maxRelative = 0.0, maxSqrtScaled = 0.0, rms = 0.0;
    /// Wall-clock time of the fit (residuals(): of the evaluation).
    double seconds = 0.0;
    /// Simplex iterations of the max-norm LPs, over all rounds and attempts (0 for least squares).
    int lpIterations = 0;
    /// Least squares: the normal equations were singular (unknowns the samples do not
    /// determine), so X is the minimum-norm minimiser (in column-equilibrated units).
    bool rankDeficient = false;
};

/// @brief The X minimising @a options.norm over @a problem's rows (see the file comment).
/// @details Least squares takes milliseconds (50,000 x 642 sparse rows) to a fraction of a
/// second (40,000 x 289 dense rows). A max-norm optimum is checked against every row (within
/// 1e-9 of the error, or rounding where the fit is nearly exact); it takes ~0.1-0.5 s for
/// 20,000-50,000 interpolation rows and tens of seconds for 40,000 dense rows of 289 harmonics.
/// @throw openvdb::ValueError for a malformed problem (no rows or no columns, inconsistent
/// arrays, a column out of range, a NaN or infinite number, a negative row weight) or options
/// (negative or non-finite ridge, valueFloor outside (0, 1])
/// @throw openvdb::RuntimeError if the LP solver or the non-negative least-squares iteration fails
FitResult fitControlValues(const FitProblem& problem, const FitOptions& options = FitOptions());

/// @brief The residual statistics of a given @a x on @a problem, measured as fitControlValues
/// reports them, so that any representation's fit can be compared the same way.
/// @throw openvdb::ValueError for a malformed problem, x.size() != problem.columns, a non-finite
/// x, or valueFloor outside (0, 1]
FitResult residuals(const FitProblem& problem, const std::vector<double>& x,
    double valueFloor = FitOptions().valueFloor);

} // namespace vdbrad
