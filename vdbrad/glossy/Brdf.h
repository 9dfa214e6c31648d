// Brdf: the glossy lobes a surface voxel may add to its diffuse albedo (thesis ch. 5).
//
// A voxel reflects f = rho_d / pi + ks * lobe(w_i, w_o): the diffuse part (the scene's `albedo`)
// is solved as before; the lobe, of reflectance ks (the `specular` grid, MTL Ks), is one of
//   - Phong, energy-normalised (Lewis 1994): (N + 2) / (2 pi) max(0, r(w_i) . w_o)^N, with r the
//     mirror direction; reflects ks of normally incident light;
//   - Blinn-Phong, normalised: (N + 2)(N + 4) / (8 pi (2^(-N/2) + N)) (n . h)^N (Akenine-Moller
//     et al., Real-Time Rendering §7.8), h the half vector;
//   - GGX (Walter et al. 2007): D(h) G2(w_i, w_o) / (4 cos_i cos_o), with the Trowbridge-Reitz
//     distribution of alpha = roughness^2 (the Disney/Blender convention) and the
//     height-correlated Smith masking-shadowing; no Fresnel term (ks is the reflectance).
// Each is symmetric in w_i and w_o (Helmholtz reciprocity). A material is given by a roughness
// in (0, 1]; the Phong exponents follow the Beckmann correspondence
//     alpha = roughness^2,   N = 2 / alpha^2 - 2,
// (roughness 0.5: N = 30), and MTL's Ns converts the other way (roughnessFromExponent).
// Real lobes lose energy where they are clipped by the horizon (grazing light) or shadowed;
// vdbrad's lobes are energy-compensated instead, as Cycles' multiscatter GGX is: value() is
//     lobe~(w_i, w_o) = d(cos_i) lobe(w_i, w_o) d(cos_o),
// with d the symmetric (Sinkhorn) scaling that makes every incidence reflect all of it
// (directional albedo 1, so ks exactly), which keeps reciprocity. d comes from the lobe's
// transfer between 128 bands of cos(theta), each row integrated by importance sampling
// (sample()), so that sharp lobes are measured as well as broad ones. The solver's discrete
// lobes are normalised the same way on the direction set (GlossySurfaces.h): closed scenes
// conserve energy and uniform glossy furnaces are exact.
//
// Directions are unit vectors in the local frame: z is the normal; both point away from the
// surface.
#pragma once

#include "vdbrad/core/Constants.h"

#include <openvdb/math/Vec3.h>

#include <string>
#include <vector>

namespace vdbrad {

enum class BrdfModel { Phong, BlinnPhong, Ggx };

/// "phong", "blinn-phong", "ggx".
const char* brdfModelName(BrdfModel model);
/// @throw openvdb::ValueError for another name
BrdfModel brdfModelFromName(const std::string& name);

class Brdf
{
public:
    /// @brief A lobe of reflectance 1 (scale by ks) and the given roughness.
    /// @throw openvdb::ValueError unless roughness is in [kMinRoughness, 1]
    Brdf(BrdfModel model, double roughness);

    /// Smallest roughness (core/Constants.h).
    static constexpr double kMinRoughness = vdbrad::kMinRoughness;

    BrdfModel model() const { return mModel; }
    double roughness() const { return mRoughness; }
    /// The Phong exponent N of this roughness (2 / alpha^2 - 2).
    double exponent() const { return mExponent; }

    /// @brief The energy-compensated lobe~(w_i, w_o) in 1/sr (see the file comment), 0 below
    /// the horizon: what the solver and the renderer reflect.
    double value(const openvdb::math::Vec3d& wi, const openvdb::math::Vec3d& wo) const;
    /// @brief The analytic model's lobe(w_i, w_o), uncompensated.
    double rawValue(const openvdb::math::Vec3d& wi, const openvdb::math::Vec3d& wo) const;
    /// The compensation d at cos(theta) @a mu (linear between the bands' centres).
    double compensation(double mu) const;
    /// @brief Directional albedo: int lobe(w_i, w_o) cos_o dw_o for w_i at cos_i, of value()
    /// (1 to the bands' resolution) or, with @a raw, of rawValue() (<= 1); a midpoint rule, for
    /// tests and documentation (sharp lobes need many samples).
    double albedo(double cosIncident, int samples = 256, bool raw = false) const;

    /// @brief A direction w_i drawn for the outgoing @a wo from uniform numbers @a u1, @a u2 in
    /// [0, 1), and its density @a pdf (per steradian): Phong around the mirror direction in
    /// proportion to its cosine power, Blinn-Phong and GGX through their half vectors'
    /// distributions. May fall below the horizon (the lobe is 0 there). For a renderer's
    /// gather: lobe cos / pdf is then nearly constant.
    openvdb::math::Vec3d sample(const openvdb::math::Vec3d& wo, double u1, double u2,
        double& pdf) const;

    /// Roughness of MTL's Ns (the Phong exponent), clamped to [kMinRoughness, 1].
    static double roughnessFromExponent(double ns);

    /// Bands of cos(theta) of the compensation.
    static constexpr int kBands = 128;

private:
    BrdfModel mModel;
    double mRoughness, mAlpha, mExponent, mNorm;
    std::vector<double> mCompensation;   // d at the bands' centres
};

} // namespace vdbrad
