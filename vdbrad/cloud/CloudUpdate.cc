// What a cloud sweep does before and after the groups' round (CloudSweeps.cc): the sources it
// carries, then the unknowns it updates from the moments the groups gathered.
#include "vdbrad/cloud/CloudTransferImpl.h"

namespace vdbrad {

CloudTransfer::Impl::Sources
CloudTransfer::Impl::sources() const
{
    Sources out;
    // Source per voxel: omega0 chi_l times the moments of the diffuse radiance, so that
    // S(s) = sum_lm c_lm Y_lm(s), plus the beam's first scattering omega0 J_beam T(s).
    const size_t M = size_t(this->M);
    const std::vector<double>& quadratureMean = phase.quadratureMean;
    std::vector<float>& source = out.source;
    std::vector<float>& beamSource = out.beam;
    source.resize(n * M);
    beamSource.resize(n);
    // Anisotropic: (alpha - 1) omega0 I_00 per voxel, the part of the isotropic source that
    // alpha adds (see the self-scattering elimination below).
    std::vector<double>& isoExcess = out.isoExcess;
    isoExcess.resize(M > 1 ? n : 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<double> c(M);
        for (size_t i = r.begin(); i != r.end(); ++i) {
            double total = 0.0;
            for (int l = 0, lm = 0; lm < int(M); ++l) {
                const double w = double(omega[i]) * chi[size_t(l)];
                for (int m = -l; m <= l; ++m, ++lm) {
                    c[size_t(lm)] = w * double(moments[i * M + size_t(lm)]);
                    total += c[size_t(lm)] * quadratureMean[size_t(lm)];
                }
            }
            // The direction set integrates this source to 4 pi x total, not exactly to its
            // isotropic part (the scattered power): scale it to that, keeping its angular shape.
            // (Subtracting each harmonic's quadrature mean instead would spread the error
            // evenly over all directions: a forward peak then leaks into backscatter, +30%
            // slab albedo at order 16.)
            const double target = c[0] * quadratureMean[0];
            const double alpha = total > 0.0 ? target / total : 1.0;
            for (size_t lm = 0; lm < M; ++lm) source[i * M + lm] = float(alpha * c[lm]);
            if (M > 1) isoExcess[i] = total > 0.0 ? (target - total) / total * c[0] : 0.0;
            beamSource[i] = omega[i] * beamJ[i];
        }
    });
    return out;
}

// Self-scattering elimination. Of what a voxel scatters isotropically, the fraction
// 1 - M_v is extinguished again in the voxel itself: the sweep maps I_00 to
// swept = rest + alpha c_v I_00 + (1 - alpha) omega0 I_00 (the second term s0 (1 - f), the
// third the quadrature of r: alpha makes the higher moments integrate to
// (1 - alpha) times the isotropic source), with c_v = omega0 (1 - M_v). In an opaque
// conservative voxel that local mode decays like c_v ~ 1 - 1 / tau per sweep. Solving the
// local term exactly,
//     I_00' = (swept - c_v I_00) / (1 - c_v)
//           = (rest - (alpha - 1) omega0 M_v I_00) / (1 - c_v),
// has the same fixed point (I_00' = I_00 iff I_00 = swept) and removes that mode; what is
// left is voxel-to-voxel diffusion, for Anderson. The beam's first scattering stays in rest
// (a constant: fixed point unchanged), and so does the light a periodic box carries over.
// 1 - c_v = (1 - omega0) + omega0 M_v, formed without cancellation in double: at the fixed
// point a conservative voxel's I_00 M_v is then exactly the light it gathers, so the energy
// balance closes however opaque it is. It is > 0 for any finite optical depth; the clamp
// only keeps voxels whose float f underflowed (tau past ~1e37 per step: nothing gets in or
// out of them) at J = 0 instead of 0 / 0. Higher moments need no elimination: a sweep maps
// I_lm to about omega0 chi_l' (1 - M_v) I_lm, and |chi_l'| < 1 for l >= 1 does not tend to
// 1 with the optical depth (delta-M keeps a forward peak's chi_l' <= K / (K + 1)), so their
// local modes decay at a rate independent of tau.
void
CloudTransfer::Impl::eliminateSelfScattering(std::vector<double>& sum,
    const std::vector<double>& isoExcess, std::vector<float>* before)
{
    const size_t M = size_t(this->M);
    if (before) before->resize(n);
    for (size_t i = 0; i < n; ++i) {
        if (before) (*before)[i] = moments[i * M];
        const double free = std::max(escapes(i), double(std::numeric_limits<float>::min()));
        const double excess = M > 1 ? isoExcess[i] * escape[i] : 0.0;
        sum[i * M] = (sum[i * M] - excess) / free;
    }
    for (size_t e = 0; e < n * M; ++e) moments[e] = float(sum[e]);
}

// Diffusion synthetic acceleration (DiffusionAcceleration.h) after the elimination: the plain
// sweep changed I_00 by r = (1 - c_v) (I_00' - I_00) (@a before: I_00 before the sweep; the
// elimination's I_00' is in @a sum), and the next iterate is the plain step plus the
// diffusion's estimate of the error left, I_00 + r + delta (with its neighbours at rest a voxel
// gets I_00' back). Kept >= 0: a negative radiance is never nearer the solution.
void
CloudTransfer::Impl::accelerateDiffusion(std::vector<double>& sum, const std::vector<float>& before)
{
    const size_t M = size_t(this->M);
    std::vector<double> r(n), delta;
    double change = 0.0, size = 0.0;
    for (size_t i = 0; i < n; ++i) {
        r[i] = escapes(i) * (sum[i * M] - double(before[i]));
        change = std::max(change, std::abs(r[i]));
        size = std::max(size, std::abs(double(before[i]) + r[i]));
    }
    if (!(change > DiffusionAcceleration::kNoise * size)) return;
    diffusion->correct(r, delta);
    for (size_t i = 0; i < n; ++i) {
        if (delta[i] == 0.0) continue;
        sum[i * M] = std::max(double(before[i]) + r[i] + delta[i], 0.0);
        moments[i * M] = float(sum[i * M]);
    }
}

// The medium's mean radiance J from the moments, its change into @a change; returns the power
// the medium absorbed (the beam's deposit and, per unit volume, 4 pi kappa J).
double
CloudTransfer::Impl::updateMeanRadiance(const std::vector<double>& sum, Change& change)
{
    const size_t M = size_t(this->M);
    double absorbed = 0.0;
    const double y00 = 1.0 / std::sqrt(4.0 * kPi);
    for (size_t i = 0; i < n; ++i) {
        const float J = float(sum[i * M] * y00);
        change.max = std::max(change.max, double(std::abs(J - diffuseJ[i])));
        change.size = std::max(change.size, double(J + beamJ[i]));
        diffuseJ[i] = J;
        absorbed += double(1.f - omega[i])
            * (deposited[i] + 4.0 * kPi * double(kappa[i]) * double(J));
    }
    return absorbed;
}

// The ground's reflected radiance, rho E / pi, is an unknown as J is: what @a landed on each
// cell replaces the last sweep's. Returns what reached the ground, all and direct.
std::pair<double, double>
CloudTransfer::Impl::updateGround(const std::vector<double>& landed, Change& change)
{
    double onGround = 0.0, directOnGround = 0.0;
    for (size_t c = 0; c < landed.size(); ++c) {
        const double k = groundAlbedo / kPi;
        change.max = std::max(change.max, k * std::abs(landed[c] - groundDiffuse[c]));
        change.size = std::max(change.size, k * (groundDirect[c] + landed[c]));
        onGround += groundDirect[c] + landed[c];
        directOnGround += groundDirect[c];
    }
    groundDiffuse = landed;
    return {onGround, directOnGround};
}

// The surfaces' radiosity, B / pi = (E A + rho (direct + landed)) / (A pi) at each voxel, is an
// unknown too: what the groups brought them replaces the last sweep's. Returns what they
// absorbed, their backs included.
double
CloudTransfer::Impl::updateSurfaces(const Sweep& sw, Change& change)
{
    const size_t surfaceCount = surfaceLanded.size();
    double surfaceAbsorbed = backDirect;
    std::vector<double> onSurface(surfaceCount, 0.0);
    for (int g = 0; g < SweepSchedule::kGroups; ++g) {
        const std::vector<double>& part = sw.onSurface[size_t(g)];
        for (size_t v = 0; v < surfaceCount; ++v) onSurface[v] += part[v];
        surfaceAbsorbed += sw.backs[size_t(g)];
    }
    for (size_t v = 0; v < surfaceCount; ++v) {
        const double rho = surfaces->albedo(v), reached = surfaceDirect[v] + onSurface[v];
        surfaceAbsorbed += (1.0 - rho) * reached;
        if (!(surfaceArea[v] > 0.0)) continue;
        const double perB = 1.0 / (kPi * surfaceArea[v]);
        change.max = std::max(change.max, rho * perB * std::abs(onSurface[v] - surfaceLanded[v]));
        change.size = std::max(change.size, double(surfaces->emission(v)) / (kPi * outputScale)
            + rho * perB * reached);
    }
    surfaceLanded = std::move(onSurface);
    return surfaceAbsorbed;
}

// What Anderson mixes: the moments of order l <= 1 (mixedMoments()) and, with periodic
// boundaries, the light carried across the side faces (in a thin periodic slab light wraps
// many times, and that carry-over is then the slowest mode), what the ground and the surfaces
// received.
std::vector<float>
CloudTransfer::Impl::mixedState() const
{
    const size_t M = size_t(this->M), K = mixedMoments();
    std::vector<float> x(n * K);
    for (size_t i = 0; i < n; ++i) {
        for (size_t k = 0; k < K; ++k) x[i * K + k] = moments[i * M + k];
    }
    x.insert(x.end(), leftFace.begin(), leftFace.end());
    x.insert(x.end(), groundDiffuse.begin(), groundDiffuse.end());
    x.insert(x.end(), surfaceLanded.begin(), surfaceLanded.end());
    return x;
}

// The next sweep starts from the mixed state; J follows it, so that the next residual measures
// that sweep's change and the output is the mixed iterate. A mixed state with negative mean
// radiance or carried power is refused (the plain step is kept). @a x: the state the sweep
// started from.
void
CloudTransfer::Impl::mix(const std::vector<float>& x)
{
    const size_t M = size_t(this->M), K = mixedMoments();
    std::vector<float> gx = mixedState();
    andersonStep(*mixer, x.data(), gx.data(), [&](const float* v) {
        for (size_t i = 0; i < n; ++i) if (!(v[i * K] >= 0.f)) return false;
        for (size_t k = n * K; k < gx.size(); ++k) if (!(v[k] >= 0.f)) return false;
        return true;
    });
    const auto faces = gx.begin() + long(n * K), lands = faces + long(leftFace.size());
    const auto onSurfaces = lands + long(groundDiffuse.size());
    for (size_t i = 0; i < n; ++i) {
        for (size_t k = 0; k < K; ++k) moments[i * M + k] = gx[i * K + k];
    }
    std::copy(faces, lands, leftFace.begin());
    std::copy(lands, onSurfaces, groundDiffuse.begin());
    std::copy(onSurfaces, gx.end(), surfaceLanded.begin());
    const double y00 = 1.0 / std::sqrt(4.0 * kPi);
    for (size_t i = 0; i < n; ++i) diffuseJ[i] = float(double(moments[i * M]) * y00);
}

} // namespace vdbrad
