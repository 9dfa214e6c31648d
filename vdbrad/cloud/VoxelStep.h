// VoxelStep: radiance across one voxel step of a naive digital line (thesis §6.3).
//
// A naive line of direction sigma advances one voxel per step along its major axis, so a step
// is exactly l = |sigma| / max_k |sigma_k| voxels long. Across a voxel of optical depth
// tau = kappa l with a source S constant over the voxel, dL/ds = kappa (S - L) gives
//
//     L_out = S + (L_in - S) e^-tau,      mean over the step: L_bar = S + (L_in - S) f(tau),
//     f(tau) = (1 - e^-tau) / tau.
//
// The mean escape factor of a voxel, M_v = sum over directions and senses of Omega f(tau)
// (weighted as the sweeps weight them), is the fraction of what it emits that leaves it: the
// cloud solver's self-scattering elimination divides by 1 - omega0 (1 - M_v).
#pragma once

#include <openvdb/openvdb.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <vector>

namespace vdbrad {

// 1 - e^-tau, where stepFactors() and linearSourceGain() take it from the exponential (tau above
// kExponentialDepth; below, series): a sweep computes it once per voxel and direction and hands
// it to both senses' steps.
constexpr float kExponentialDepth = 1e-3f;
inline double
absorbedFraction(float tau)
{
    return -std::expm1(-double(tau));
}

// Across a step of optical depth tau: the absorbed fraction 1 - e^-tau and the mean factor
// (1 - e^-tau) / tau, with one exponential (@a a = absorbedFraction(tau), read only above
// kExponentialDepth), and without cancellation for thin voxels. The radiance is updated as
// L += (S - L) (1 - e^-tau) rather than S + (L - S) e^-tau: at tau = 1e-8 e^-tau rounds to 1 in
// float and the latter would lose all the light a thin voxel adds.
inline void
stepFactors(float tau, double a, float& absorb, float& mean)
{
    if (tau > kExponentialDepth) {
        absorb = float(a);
        mean = float(a / double(tau));
    } else {
        // Series to tau^3: relative error below 1e-12 here.
        absorb = tau * (1.f - 0.5f * tau * (1.f - tau / 3.f));
        mean = 1.f - 0.5f * tau * (1.f - tau / 3.f * (1.f - 0.25f * tau));
    }
}

inline void
stepFactors(float tau, float& absorb, float& mean)
{
    stepFactors(tau, tau > kExponentialDepth ? absorbedFraction(tau) : 0.0, absorb, mean);
}

// Across a step of optical depth tau whose source rises linearly from S - S1 / 2 at the entry to
// S + S1 / 2 at the exit (mean S): L_out = S + (L_in - S) e^-tau + S1 h(tau), and the mean
// radiance over the step loses S1 h(tau) / tau, with
//     h(tau) = 1 - (1 - e^-tau) / 2 - (1 - e^-tau) / tau   (tau^2 / 12 for thin steps, 1/2 opaque).
// Returns h; @a perTau gets h / tau. Series below tau = 0.1 (the closed form cancels there).
// With the step's factors (stepFactors(), the same numbers) from one exponential, @a a as
// there.
inline float
linearSourceGain(float tau, double a, float& perTau, float& absorb, float& mean)
{
    if (tau > 0.1f) {
        const double t = tau;
        absorb = float(a);
        mean = float(a / t);
        const double h = 1.0 - 0.5 * a - a / t;
        perTau = float(h / t);
        return float(h);
    }
    stepFactors(tau, a, absorb, mean);
    // tau^2 / 12 - tau^3 / 24 + tau^4 / 80 - tau^5 / 360: relative error below 1e-6 here.
    perTau = tau * (1.f / 12.f - tau * (1.f / 24.f - tau * (1.f / 80.f - tau / 360.f)));
    return tau * perTau;
}

inline float
linearSourceGain(float tau, float& perTau, float& absorb, float& mean)
{
    return linearSourceGain(tau, tau > kExponentialDepth ? absorbedFraction(tau) : 0.0, perTau,
        absorb, mean);
}

/// Axes along which the medium does not vary (a periodic box one voxel deep): flat[k].
using FlatAxes = std::array<bool, 3>;

/// @brief How direction @a sigma is swept through a medium that does not vary along the
/// @a flat axes. Without them: sigma's own naive line, one voxel per step of its major axis, a
/// step of |sigma| / max_k |sigma_k| voxels (float: the sweeps' and the self-scattering
/// factors' optical depths must be the same numbers). Along a flat axis the radiance does not
/// vary either, so a 3D line is swept as its projection: the naive line of sigma with the flat
/// components zeroed (reduced by their gcd), each of its steps a 3D path of |sigma| / max over
/// the other axes of |sigma_k| voxels. A direction with only flat components (its projection
/// is a point) stays in the same voxel's medium forever: its lines are `isolated`, one voxel
/// each and infinitely long (the radiance starts from zero in every voxel); the sigma swept is
/// then +1 along the first other axis (a zero component of sigma takes its pattern's sign, so
/// that sign always matches the visiting order).
struct SweptLine
{
    openvdb::Coord sigma;   ///< the digital line swept
    openvdb::Vec3d unit;    ///< its unit vector (which side faces and layers it crosses)
    float step = 1.f;       ///< 3D path per step, voxels (kIsolatedStep if isolated)
    bool isolated = false;
};
/// An isolated line's step: any voxel with extinction is opaque along it, a clear one clear.
constexpr float kIsolatedStep = 1e30f;
SweptLine sweptLine(const openvdb::Coord& sigma, const FlatAxes& flat = FlatAxes{});

/// @brief Per voxel of optical depth per voxel length @a kappa, the mean escape factor
/// sum_d weight[d] f(kappa step[d]), from the sweeps' own float factors (so that the
/// elimination matches the sweeps exactly); voxels of equal kappa in a row share one sum (a
/// homogeneous cloud computes it once per range).
std::vector<double> meanEscapeFactors(const std::vector<float>& kappa,
    const std::vector<float>& step, const std::vector<double>& weight);

} // namespace vdbrad
