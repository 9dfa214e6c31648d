// DiffusionAcceleration: diffusion synthetic acceleration of a cloud's source iteration.
//
// Source iteration converges like the fraction of scattered light that scatters again: in a
// cloud hundreds of optical depths across the slowest modes are smooth ones (diffusion), which
// decay like 1 - O(1 / tau^2) per sweep; Anderson over a few moments (CloudTransfer.h) removes
// a handful of them, not the many a large cloud has (WDAS 1/16 at g 0.877: ~0.9x per
// iteration). Diffusion synthetic acceleration (Alcouffe 1977; Adams & Larsen 2002) solves for
// the error those modes carry with the diffusion equation, cheap next to a sweep: after a
// plain sweep changed the isotropic moment by r_v, the light the sweep's sources missed,
// sigma_s r per unit volume, is spread by
//
//     -div D grad delta + sigma_a delta = sigma_s r,      D = 1 / (3 sigma_tr),
//     sigma_tr = sigma_t (1 - omega0 chi_1)   (delta-M scaled: the same as unscaled),
//
// and the next iterate is the plain step plus delta. At the fixed point r = 0, so delta = 0:
// the transport solution is unchanged, only reached sooner.
//
// Discretisation: one unknown per medium voxel, finite volumes over its six faces (lengths in
// voxels, kappa = sigma_t per voxel length). A face between two medium voxels conducts
// k_a k_b / (k_a + k_b), each half voxel's conductance k = 2 D. Faces onto nothing (outside the
// box, a gap of a sparse cloud, a voxel without extinction) lose delta_v / (1 / k + 2) (Marshak's
// vacuum condition, J = phi / 2); onto a reflecting wall of albedo rho (a ground, a surface
// voxel) delta_v / (1 / k + 2 (1 + rho) / (1 - rho)). A periodic box wraps its horizontal faces.
//
// Consistency with the sweeps in thick voxels. Cell-centred diffusion is not the transport
// scheme's own low-order limit: in a voxel of optical depth tau >> 1 a sweep re-collides the
// fraction c = omega0 (1 - M_v) of what the voxel scatters (M_v its mean escape factor), and
// a voxel's error mode that alternates from voxel to voxel decays like c per sweep, where
// cell-centred diffusion would predict 1 - 4 / (tau tau_tr): it over-corrects that mode by
// ~tau_tr / 5 and diverges past tau_tr ~ 10 (the known inconsistency of DSA in thick cells).
// The half voxel's conductance is therefore at least X_v / 3, X_v = kappa M_v / (1 - M_v):
// with its neighbours at zero a voxel then gets exactly the self-scattering elimination's
// correction (CloudTransfer's eliminateSelfScattering), whatever its optical depth. Where
// tau_tr per voxel is below ~3, as in clouds at their usual resolutions, 2 D is larger and the
// diffusion is the textbook one; above, smooth modes are under-corrected (still stable, and
// left to Anderson). Voxels thinner than kMinDepth count as that thick in D: their light
// crosses many voxels anyway, and conductances without bound would ruin the solver's
// conditioning.
//
// The linear system is symmetric positive definite (any medium voxel has a leaking or absorbing
// path) and solved by conjugate gradients with a Jacobi preconditioner to a relative residual
// of kTolerance: the correction need not be exact (the next sweep measures what is left), and
// sums run over fixed blocks in a fixed order, so the result does not depend on the thread
// count.
#pragma once

#include "vdbrad/core/VoxelIndex.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

namespace vdbrad {

class DiffusionAcceleration
{
public:
    /// Voxels thinner than this (optical depth per voxel) are this thick in D.
    static constexpr double kMinDepth = 0.01;
    /// Conjugate gradients stop at this residual relative to the right-hand side's...
    static constexpr double kTolerance = 1e-4;
    /// ...or after this many iterations.
    static constexpr int kMaxIterations = 2000;
    /// A sweep's change below this fraction of the radiance is left alone: that near the
    /// float sweeps' rounding, the diffusion would amplify their noise (its smooth modes by up
    /// to ~tau^2) instead of an error.
    static constexpr double kNoise = 1e-5;
    /// Phase functions more backward than this asymmetry are not accelerated: their error
    /// modes change sign from sweep to sweep and the diffusion amplifies them (a conservative
    /// slab of optical depth 2: sweeps to 1e-6 with / without at g -0.6 24 / 35, -0.75 36 / 39,
    /// -0.8 44 / 42, -0.9 78 / 52; -0.99 diverged).
    static constexpr double kMinAsymmetry = -0.7;
    /// Not a medium voxel: a wall of albedo wall[v] (< 0: nothing, a vacuum).
    static constexpr float kMedium = std::numeric_limits<float>::infinity();

    /// @param voxels  the medium solved (the sweeps' voxels)
    /// @param kappa   optical depth per voxel length, delta-M scaled (the sweeps')
    /// @param omega   single-scattering albedo, scaled
    /// @param escape  mean escape factor M_v (CloudTransfer's self-scattering elimination)
    /// @param chi1    the scaled phase function's first Legendre coefficient
    /// @param wall    per voxel: kMedium where it is part of the medium diffused (it needs
    ///                kappa > 0 and M_v > 0 too), else the albedo of the wall it is (< 0: none)
    /// @param period  a periodic box: its horizontal faces (the axes other than @a up) wrap
    DiffusionAcceleration(const VoxelIndex& voxels, const std::vector<float>& kappa,
        const std::vector<float>& omega, const std::vector<double>& escape, double chi1,
        const std::vector<float>& wall, const std::optional<openvdb::CoordBBox>& period, int up);

    /// @brief The diffusion estimate @a delta (per voxel, zero outside the medium diffused) of
    /// the error left after a plain sweep that changed the isotropic moment by @a residual.
    /// Returns the conjugate-gradient iterations taken.
    int correct(const std::vector<double>& residual, std::vector<double>& delta) const;

    /// Medium voxels diffused.
    size_t size() const { return mVoxel.size(); }
    /// Bytes held for @a voxels voxels (an upper bound, every one diffused), and while
    /// correcting.
    static size_t bytes(size_t voxels);

private:
    static constexpr int kFaces = 6;
    static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
    size_t mVoxels = 0;
    std::vector<uint32_t> mVoxel;           // unknown -> voxel
    std::vector<uint32_t> mNeighbour;       // unknown x 6 -> unknown (kNone: no coupling)
    std::vector<double> mCoupling;          // unknown x 6: the face's conductance
    std::vector<double> mDiagonal;          // absorption + every face's loss
    std::vector<double> mSource;            // kappa omega0: the residual's weight
};

} // namespace vdbrad
