// GlossyOptions: how a solve represents glossy voxels' lobes (GlossySurfaces.h), apart from the
// class itself so that the solvers' public options do not install the glossy internals.
#pragma once

#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/glossy/ControlPoints.h"
#include "vdbrad/glossy/SphericalFit.h"

namespace vdbrad {

/// How a glossy voxel's distributions are represented (see the file comment).
enum class GlossyBasis { ControlPoints, Harmonics };
/// "points", "harmonics".
const char* glossyBasisName(GlossyBasis basis);

struct GlossyOptions
{
    GlossyBasis basis = GlossyBasis::ControlPoints;
    /// Control points per distribution: 12, 42, 162 (the thesis' default), 642 or 2562.
    int controlPoints = 162;
    /// Harmonics' order L ((L + 1)^2 coefficients per distribution; 1..SphericalHarmonics::
    /// kMaxOrder): 8 keeps 81, about the data of 42-162 points.
    int harmonicOrder = 8;
    BrdfModel model = BrdfModel::Phong;
    /// How kernels are rotated into the normals' frames (ControlPoints.h).
    ControlPoints::RotationKind rotation = ControlPoints::RotationKind::Resampled;
    /// The kernels' fit (ControlBrdf.h).
    FitNorm fit = FitNorm::LeastSquares;
};

} // namespace vdbrad
