// GlossySurfaces: what the radiosity sweeps need to carry glossy voxels (thesis ch. 5).
//
// A glossy voxel reflects rho_d / pi + ks lobe (Brdf.h). Its diffuse part is solved as every
// voxel's (RadiositySolver.h); its lobe adds, per voxel, the reflected radiance S at the control
// points (ControlPoints.h, in the world frame), so that what it sends along t is
//     B_d + S(t),   S(t) = sum_o omega_o(t) S_o,
// the interpolation weights omega of a sweep direction being the same for every voxel (§5.2.5):
// one lookup per direction, three loads per sender. A glossy receiver splats what it sees along
// s onto the points of s, I_i += w_s omega_i(s) L (the local deformation's weights), and at the
// end of each iteration reflects it:
//
//     S = ks (A_c I) / r_v,     A_c = D_c Q_c K Q_c^T D_c,
//
//   - K: the lobe's kernel in the local frame (ControlBrdf.h), one per distinct roughness;
//   - Q_c: the rotation into the frame of the voxel's normal (ControlPoints::rotation: local
//     values to world values; its transpose moves a measure the other way), one per normal
//     class c (the normals that occur; beyond kMaxClasses they are rounded to the nearest of
//     2562 directions, ~2.3 degrees: voxelised and level-set normals repeat a lot);
//   - D_c: the symmetric (Sinkhorn) scaling that makes A_c h_c = 1, with h_c the points' share of
//     the direction set's cosine weights for that normal (I for uniform light of value 1). A_c is
//     symmetric, so that this one condition makes uniform light reflect uniformly and conserves
//     energy for light from any direction (the discrete lobe reflects exactly ks);
//   - r_v = A_c h_v: the voxel's own share h_v, measured in the first sweep over the directions
//     that meet something (closed rooms, as the diffuse part's hit normalisation): a closed box
//     of uniform glossy material and emission is exact voxel by voxel.
// The voxel's radiosity (its exitance) is B_d + sum_o e_o S_o, e_c = h_c / sum h_c.
//
// Harmonics (GlossyBasis::Harmonics, the thesis' alternative, for comparisons): S and I are
// (L + 1)^2 real spherical-harmonic coefficients (SphericalHarmonics.h), a sender adds
// sum_b Y_b(t) S_b, a receiver splats w_s Y_b(s) L on every coefficient, and
//
//     S = ks A_c I,   A_c = D_c K D_c^T / Z_c + Delta_c,
//
// with K the lobe's projection (HarmonicBrdf.h), D_c the rotation into the normal's frame
// (Ivanic-Ruedenberg blocks), Z_c = sum of the hemisphere's cosine weights, and Delta_c the
// smallest symmetric correction (in the Frobenius norm; Powell's symmetric update) that makes
// A_c h_c = u, u the coefficients of the constant 1: K is not positive, so the control
// points' symmetric scaling does not apply, but a symmetric A_c with A_c h_c = u conserves
// energy in the same way (e_c . S = u . I / Z_c with e_c = h_c / Z_c). A voxel whose measured
// directions miss some of the hemisphere (closed rooms) gets its own Z_v and correction for
// its measured h_v (2 (L + 1)^2 more doubles for that voxel): A_v h_v = u, so that closed
// uniform furnaces stay exact.
//
// Memory: per glossy voxel, P values per channel for S and P floats for r_v, and each
// accumulator group's I (8) on the points its directions reach (two opposite octants: ~64 of
// 162; RadiositySolver) (P = 162: ~3.5 KB grey); per class, its rotation and scaling (~5 KB);
// per lobe, K (P^2 floats, 105 KB, and over its support in float and double). A scene without
// glossy voxels allocates none of it.
//
// Time: the reflection is one dense product over the lobe's support per voxel (Eigen's, ~100^2
// for 162 points), the sweeps three loads per glossy sender and three splats per glossy receiver
// per direction (docs/journal/2026-12-05-glossy-surfaces.md). Harmonics: (L + 1)^2 loads and
// splats instead of three, and a reflection of two rotations (~L^3) and one dense N^2 product:
// 3-4x the control points' solve at L = 8
// (docs/journal/2026-12-05-spherical-harmonics-whole-solve.md).
#pragma once

#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/glossy/ControlBrdf.h"
#include "vdbrad/glossy/ControlPoints.h"
#include "vdbrad/glossy/GlossyOptions.h"
#include "vdbrad/glossy/HarmonicBrdf.h"
#include "vdbrad/glossy/SphericalFit.h"
#include "vdbrad/glossy/SphericalHarmonics.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/sweep/DirectionSet.h"

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace vdbrad {


class GlossySurfaces
{
public:
    static constexpr uint32_t kNone = UINT32_MAX;
    /// Distinct normals kept exactly; beyond, normals are rounded (see the file comment).
    static constexpr size_t kMaxClasses = 4096;
    /// Roughness is rounded to this step to share kernels: roughnessKey() numbers the steps,
    /// roughnessOf() gives a step's roughness (in [Brdf::kMinRoughness, 1]).
    static constexpr double kRoughnessStep = 0.01;
    static long roughnessKey(double roughness) { return std::lround(roughness / kRoughnessStep); }
    static double roughnessOf(long key);

    /// @brief The glossy voxels of @a scene (specular > 0 in some channel), their lobes and
    /// rotations, and the weights of every direction of @a directions.
    /// @throw openvdb::ValueError for a bad control-point count
    GlossySurfaces(const Scene& scene, const DirectionSet& directions,
        const GlossyOptions& options = GlossyOptions());
    ~GlossySurfaces();

    /// Glossy voxels, and the values per distribution (control points, or coefficients).
    size_t size() const { return mVoxel.size(); }
    size_t points() const { return mValues; }
    /// Whether distributions are harmonic coefficients (GlossyBasis::Harmonics).
    bool harmonics() const { return bool(mHarmonics); }
    const ControlPoints& controlPoints() const { return mPoints; }
    const GlossyOptions& options() const { return mOptions; }
    /// The glossy index of scene voxel @a i, or kNone.
    uint32_t glossyOf(size_t i) const { return mGlossyOf[i]; }
    /// The scene voxel of glossy voxel @a g.
    uint32_t voxel(size_t g) const { return mVoxel[g]; }
    size_t classes() const;
    size_t lobes() const { return mLobes.size() + mHarmonicLobes.size(); }
    /// Lobe @a l's kernel (control points only).
    const ControlBrdf& lobe(size_t l) const { return *mLobes[l]; }
    /// Seconds spent fitting kernels and building the classes.
    double setupSeconds() const { return mSetupSeconds; }

    /// The interpolation of direction pair @a k's unit direction (@a negative: of its opposite).
    /// Control points only.
    const ControlPoints::Weights& toward(size_t k, bool negative) const
    {
        return mToward[2 * k + (negative ? 1 : 0)];
    }
    /// Harmonics only: Y(direction pair @a k's unit direction, or its opposite), points()
    /// values.
    const float* harmonicToward(size_t k, bool negative) const
    {
        return &mHarmonicToward[(2 * k + (negative ? 1 : 0)) * mValues];
    }
    /// @brief out += @a value splatted along @a dir (need not be unit) as the sweeps splat:
    /// on its three points, or on every coefficient (Y(dir) value).
    void splat(const openvdb::math::Vec3d& dir, const openvdb::Vec3f& value,
        openvdb::Vec3f* out) const;

    /// @brief The points on which directions @a ks of @a directions (both senses) splat, in
    /// increasing order: a sweep group's directions reach only these (RadiositySolver).
    static std::vector<uint32_t> splatPoints(const ControlPoints& points,
        const DirectionSet& directions, const std::vector<size_t>& ks);

    /// @brief Take voxel @a g's measured share of the points, h_v (P values, the splat of the
    /// cosine weights of the directions that met something); null: the full hemisphere's h_c
    /// (a voxel open to the sky loses what leaves, as its diffuse part does). Harmonics: the
    /// voxel gets its own correction (see the file comment).
    void setShare(size_t g, const double* share);

    /// @brief S = ks (A_c I) / r_v for glossy voxel @a g from its splatted light @a incident
    /// (P values), written to @a out (P values). T: float, double, Vec3f, Vec3d.
    template<typename T>
    void reflect(size_t g, const T* incident, T* out) const;

    /// @brief The distribution @a S (points() values) along @a dir: interpolated on the
    /// points, or sum_b Y_b(dir) S_b.
    template<typename T>
    T evaluate(const T* S, const openvdb::math::Vec3d& dir) const;

    /// @brief The voxel's lobe's exitance: sum_o e_o S_o.
    template<typename T>
    T exitance(size_t g, const T* S) const;

    /// Bytes held, not counting the solver's per-voxel arrays.
    size_t memUsage() const;

    /// One line: glossy voxels, points, lobes, classes, model.
    std::string describe() const;

private:
    struct Class;
    // The constructor's steps, in order: the glossy voxels, the lobes' kernels (returns each
    // glossy voxel's lobe), the (normal, lobe) classes, then each class's rotation and scaling
    // and the directions' weights, for harmonics or for control points.
    void findGlossyVoxels(const Scene& scene);
    std::vector<uint32_t> fitLobes(const Scene& scene);
    void findClasses(const Scene& scene, const std::vector<uint32_t>& lobe);
    void setupHarmonics(const DirectionSet& directions);
    void setupPoints(const DirectionSet& directions);
    void setupPointClass(Class& c, const DirectionSet& directions) const;
    // D_c: the symmetric (Sinkhorn) scaling that makes A_c h_c = 1 (see the file comment).
    void scaleSymmetrically(Class& c) const;
    // Harmonics: Powell's correction Delta x = (q (h . x) + h (q . x) - (q . h)(h . x) h / |h|^2)
    // / |h|^2 for a share h of total weight Z, with q = u - D K D^T h / Z.
    struct Normaliser
    {
        std::vector<double> h, q;
        double z = 0.0, hh = 0.0, qh = 0.0;
    };
    void normalise(const Class& c, std::vector<double> h, Normaliser& norm) const;
    template<typename T> using Scalar = typename openvdb::VecTraits<T>::ElementType;
    template<typename T> void product(const Class& c, const T* in, T* out,
        std::vector<Scalar<T>>& a, std::vector<Scalar<T>>& b) const;
    template<typename T> void reflectHarmonic(size_t g, const T* incident, T* out) const;
    void setupHarmonicClass(Class& c, const DirectionSet& directions) const;
    void reflectHarmonicRaw(const Class& c, const Normaliser& norm, const double* in,
        double* out) const;
    GlossyOptions mOptions;
    ControlPoints mPoints;
    std::unique_ptr<SphericalHarmonics> mHarmonics;
    size_t mValues = 0;
    std::vector<std::unique_ptr<HarmonicBrdf>> mHarmonicLobes;
    std::vector<float> mHarmonicToward;
    const Scene& mScene;
    std::vector<uint32_t> mGlossyOf, mVoxel, mClassOf;
    std::vector<std::unique_ptr<ControlBrdf>> mLobes;
    std::vector<Class> mClasses;
    std::vector<ControlPoints::Weights> mToward;
    // Per glossy voxel, P values: 1 / r_v (0 where r_v ~ 0); harmonics: the normalisation
    // of a voxel that measured a share other than its class's (null: the class's).
    std::vector<float> mInvShare;
    std::vector<std::unique_ptr<Normaliser>> mVoxelNorm;
    double mSetupSeconds = 0.0;
};

} // namespace vdbrad
