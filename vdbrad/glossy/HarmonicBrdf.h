// HarmonicBrdf: a glossy lobe (Brdf.h) as a kernel on real spherical harmonics, the thesis'
// alternative to control points (§5.2; SphericalHarmonics.h), for whole solves that compare the
// two representations on the same scenes (GlossyOptions::basis).
//
// The solver then keeps, per glossy voxel, the light it receives as harmonic coefficients
// (I_b = sum over incoming directions s of w_s B(s) Y_b(s)) and the reflected radiance S (times
// pi, the solver's radiosity units) as coefficients, S_a = sum_b K_ab I_b / Z, with
//
//     K_ab = int int Y_a(w_o) pi lobe(w_i, w_o) Y_b(w_i) dw_i dw_o,
//
// the lobe extended evenly below the horizon, lobe(w_i, w_o) = lobe(w_i', w_o') with ' the
// mirror image in the tangent plane: no light comes from there and none is sent there, so the
// kernel's values there are free, and the even extension is continuous at the horizon where
// the lobe cut to 0 rings (Gibbs) over ~180/L degrees above it: at L = 8, Phong of roughness
// 0.7, the worst error is 4.2 % of the peak (29 % if cut to 0; tests/test_glossy.cc). K is
// the least-squares (L2) projection of the extended lobe, both arguments truncated at order L,
// and only the harmonics even in the local z carry it (Y_lm(x, y, -z) = (-1)^(l+m) Y_lm):
// (L + 1)(L + 2) / 2 of them, all of them once rotated into a normal's frame. Z, the cosine
// weights' sum, is the solver's (GlossySurfaces.h). Uniform light then reflects to the constant
// 1 on the whole sphere, which the solver's normalisation makes exact on the direction set. The
// inner integral over w_o is importance-sampled from the lobe (Brdf::sample, a fixed
// stratified 16 x 16 grid per w_i: sharp lobes are integrated as well as broad ones), the outer
// one is a quadrature of the upper hemisphere; K is then made symmetric (reciprocity).
//
// Unlike the control points' kernel, K is not positive: a truncated lobe rings, and the reflected
// light may be negative in directions away from a sharp lobe. That is a property of the basis, kept
// as it is, so that the comparison is honest (docs/journal/2026-12-05-glossy-surfaces.md).
#pragma once

#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/glossy/SphericalHarmonics.h"
#include "vdbrad/glossy/SymmetricKernel.h"

#include <vector>

namespace vdbrad {

class HarmonicBrdf
{
public:
    /// @brief Project @a brdf's lobe on @a harmonics' basis (kept by reference).
    HarmonicBrdf(const SphericalHarmonics& harmonics, const Brdf& brdf);

    const SphericalHarmonics& harmonics() const { return *mHarmonics; }
    const Brdf& brdf() const { return mBrdf; }
    /// Coefficients per distribution: (L + 1)^2.
    size_t size() const { return mHarmonics->size(); }
    /// K, symmetric, size()^2 values.
    const std::vector<double>& kernel() const { return mKernel.wide(); }
    /// @brief out = K in: @a in and @a out hold @a width columns (channels) of size() values.
    /// S: float or double.
    template<typename S> void apply(const S* in, S* out, int width) const
    {
        mKernel.apply(in, out, width);
    }

    /// @brief The truncated pi lobe(wi, wo): sum_ab Y_a(wo) K_ab Y_b(wi) (local frame).
    double value(const openvdb::math::Vec3d& wi, const openvdb::math::Vec3d& wo) const;
    double seconds() const { return mSeconds; }

private:
    const SphericalHarmonics* mHarmonics;
    Brdf mBrdf;
    SymmetricKernel mKernel;
    double mSeconds = 0.0;
};

} // namespace vdbrad
