// ControlBrdf: a glossy lobe (Brdf.h) as a kernel on control points (thesis §5.2, §5.3).
//
// The solver keeps, per glossy voxel, the light it receives splatted on the control points
// (a measure: I_i = sum over incoming directions s of w_s L(s) omega_i(s), with the cosine
// weights w_s and the interpolation weights omega_i), and reflects it with
//
//     S_o = sum_i K_oi I_i,
//
// S the reflected radiance (times pi, the solver's radiosity units) at the control points, per
// unit of the lobe's reflectance ks. Column i of K is the lobe for light arriving from control
// point c_i: the values X at the points whose interpolation fits pi lobe(c_i, w) best over a fine
// quadrature of the upper hemisphere (SphericalFit.h: least squares, the thesis' final choice,
// or the max-norm linear programs), then clamped at 0 (radiance is never negative). Light from
// just above the horizon lands on points below it: their columns fit the lobe of the direction
// lifted to 2 degrees above the horizon; points more than a grid spacing below it receive
// nothing, and their columns stay empty. K is then made symmetric, (K + K^T) / 2, which is the
// Helmholtz reciprocity of the fitted lobe: sum_oi omega_o(a) K_oi omega_i(b) is symmetric in
// the directions a and b.
//
// K is in the local frame (z = normal); the solver rotates it into each normal's frame and
// normalises it on the direction set (GlossySurfaces.h).
#pragma once

#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/glossy/ControlPoints.h"
#include "vdbrad/glossy/SphericalFit.h"
#include "vdbrad/glossy/SymmetricKernel.h"

#include <vector>

namespace vdbrad {

class ControlBrdf
{
public:
    /// @brief Fit @a brdf's lobe on @a points (kept by reference: must outlive this).
    /// @param norm  the fit's error norm
    /// @param cuts  quadrature refinement per finest triangle (ControlPoints::quadrature)
    ControlBrdf(const ControlPoints& points, const Brdf& brdf,
        FitNorm norm = FitNorm::LeastSquares, int cuts = 4);

    const ControlPoints& points() const { return *mPoints; }
    const Brdf& brdf() const { return mBrdf; }
    size_t size() const { return mPoints->size(); }
    /// K, row-major: kernel()[o * size() + i].
    const std::vector<float>& kernel() const { return mKernel; }
    /// Points whose row or column of K is not zero (the upper hemisphere and the horizon's
    /// band): the solver's products run over these only.
    const std::vector<uint32_t>& support() const { return mSupport; }
    /// @brief out = K in restricted to the support: @a in and @a out hold @a width columns
    /// (channels) of support().size() values each, in support order. S: float or double.
    template<typename S> void apply(const S* in, S* out, int width) const
    {
        mCompact.apply(in, out, width);
    }

    /// @brief The fitted pi lobe(wi, wo): sum_oi omega_o(wo) K_oi omega_i(wi) (local frame).
    double value(const openvdb::math::Vec3d& wi, const openvdb::math::Vec3d& wo) const;

    /// Fit statistics over the columns of incoming points above the horizon, relative to each
    /// column's peak pi lobe: the worst absolute error and the root mean square.
    double maxError() const { return mMaxError; }
    double rmsError() const { return mRmsError; }
    double seconds() const { return mSeconds; }

private:
    const ControlPoints* mPoints;
    Brdf mBrdf;
    std::vector<float> mKernel;
    std::vector<uint32_t> mSupport;
    // K over the support, dense, in both precisions: the solver's reflections are one small
    // matrix product each (Eigen's, vectorised).
    SymmetricKernel mCompact;
    double mMaxError = 0.0, mRmsError = 0.0, mSeconds = 0.0;
};

} // namespace vdbrad
