// HarmonicQuadrature: direction weights that integrate spherical harmonics exactly.
//
// A DirectionSet's factors are the solid angles of its cells on the discrete sphere: they add up
// to 4 pi exactly but integrate a harmonic of order l only roughly (order 8 a few per cent off,
// order 16 tens of per cent on a 303-pair set). The cloud solver projects the radiance on
// harmonics up to order K and evaluates the source from them, so the product of two order-K
// harmonics must integrate exactly: otherwise the projection aliases (a higher K makes slabs
// worse, not better). The fix is the smallest change to the weights that makes the set exact
// for every harmonic up to a degree D:
//
//     minimise sum_k (A'_k - A_k)^2 / A_k   subject to   sum_k A'_k Y_lm(s_k) = (2 / sqrt(4 pi))
//                                                       delta_l0,  l even <= D,
//
// (odd orders integrate to zero by the pairs' point symmetry; the pair weight A counts both
// senses). The relative scaling keeps small cells small. The minimum-norm solution is
// A' = A + W C^T lambda, found by Gram-Schmidt on the weighted constraint rows (rows the set
// cannot tell apart are dropped: its symmetries make some dependent). Weights must stay
// positive (a negative solid angle would amplify light): the highest degree whose fit keeps
// every weight above a quarter of its cell is used.
#pragma once

#include "vdbrad/sweep/DirectionSet.h"

#include <vector>

namespace vdbrad {

/// Highest degree fitted: (D + 1)(D + 2) / 2 constraints cost O(constraints^2 x pairs) to fit.
constexpr int kMaxQuadratureDegree = 32;

struct HarmonicQuadrature
{
    /// Pair factors (DirectionSet::factor's units: they add up to 2).
    std::vector<double> factors;
    /// The even degree D integrated exactly (0: the cells' own weights were kept).
    int degree = 0;
    /// max |sum_k A'_k Y_lm(s_k) - exact| over the harmonics up to D, after the fit.
    double residual = 0.0;
};

/// @brief Weights for @a directions that integrate harmonics up to degree @a degree exactly,
/// or up to the highest even degree below it that keeps them positive (see the file comment).
HarmonicQuadrature fitHarmonicQuadrature(const DirectionSet& directions, int degree);

} // namespace vdbrad
