// MaxNormFit: what SphericalFit.cc (least squares, statistics) and MaxNormFit.cc (the max norms'
// linear programs) share, inside the library only.
#pragma once

#include "vdbrad/glossy/SphericalFit.h"

#include <vector>

namespace vdbrad {
namespace fit {

/// max_k |Y_k|: the LPs' unit of the targets, and the scale of the relative measures' floor.
double maxAbsTarget(const FitProblem& p);

/// @brief The X minimising @a options.norm, a max norm, over the rows of a validated @a p (see
/// MaxNormFit.cc); @a iterations receives the simplex iterations of every round and attempt.
/// @throw openvdb::ValueError if the LP would have too many rows for GLPK
/// @throw openvdb::RuntimeError if the simplex fails under every setup
std::vector<double> maxNorm(const FitProblem& p, const FitOptions& options, int& iterations);

} // namespace fit
} // namespace vdbrad
