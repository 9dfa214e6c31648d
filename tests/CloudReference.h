// Independent references for solar radiative transfer in a homogeneous cloud. They share no code
// with vdbrad's discrete-ordinate cloud solver, so agreement between the two means something:
//
//  - slabMonteCarlo / boxMonteCarlo: analogue photon Monte Carlo in an infinite plane-parallel slab
//    (periodic horizontal boundaries are the same thing) and in an axis-aligned box with open
//    boundaries, lit by a parallel solar beam.
//  - columnsMonteCarlo / voxelMediumMonteCarlo: delta tracking through periodic columns and
//    through a voxel medium (a 3D cloud, open or periodic), for the heterogeneous benchmarks.
//  - deltaEddingtonAlbedo / deltaEddingtonTransmittance: the delta-Eddington two-stream
//    approximation for a slab over a black surface (Joseph, Wiscombe & Weinman 1976).
//  - addingDoublingSlab: a deterministic, numerically exact (to quadrature and start-layer error)
//    adding-doubling solution of the azimuthally averaged slab problem, for noise-free checks
//    (|g| <= 0.95: sharper peaks defeat its quadrature).
//  - slabOverGround: the same slab over a Lambertian ground, by adding the ground to the
//    doubling's slab (its plane and spherical albedo and transmittance).
//  - chandrasekharH: the H-function for isotropic scattering (semi-infinite albedo), which
//    anchors the doubling to a published value.
//
// Conventions: y is up. The sun direction (pointing TO the sun) for zenith angle theta0 and
// azimuth phi0 is s = (sin th0 cos ph0, cos th0, sin th0 sin ph0); photons travel along -s. Every
// result is a fraction of the beam power entering the medium. Reflectance counts photons leaving
// with d.y > 0, transmittance those leaving with d.y <= 0 (d.y == 0 has probability zero), and the
// direct transmittance is the part of the transmittance that never scattered.
//
// Ground: the slab, column and voxel problems may sit on a Lambertian ground of albedo rho
// (groundAlbedo; 0, the default, is black and reproduces the results without a ground bit for bit).
// Then transmittance is the downward flux reaching the ground per unit entering power, counting
// every arrival (a photon may arrive many times, so it can exceed the black-ground value and 1),
// directTransmittance the unscattered first arrivals, and groundAbsorptance the fraction the
// ground absorbs: R + A + groundAbsorptance = 1, and groundAbsorptance = (1 - rho) T in
// expectation. Over a black ground, groundAbsorptance = T. The Monte Carlo's transmittance is then
// a mean count of arrivals per photon, and its standard error that count's sample variance.
//
// Monte Carlo estimator (analogue): free paths are exact exponential variates, s = -ln(U) / sigma;
// at a collision the photon scatters with probability omega0, else it is absorbed. Each photon
// ends in exactly one of {reflected, transmitted, absorbed}, so the fractions are multinomial
// means: unbiased, R + T + A = 1 up to one rounding of the divisions, A = 0 exactly when
// omega0 = 1, and the standard error of each fraction p is sqrt(p (1 - p) / N). Photons run in
// fixed chunks of kPhotonsPerChunk, each chunk with its own generator seeded from (seed, chunk);
// the tallies are integer counts, so the result is bit-identical for any thread count.
//
// Phase function: Henyey-Greenstein, p(cos Th) = (1 - g^2) / (1 + g^2 - 2 g cos Th)^(3/2),
// normalised to (1/4pi) int p dOmega = 1; g = 0 is exactly isotropic (see sampleHenyeyGreenstein).
#pragma once

#include <tbb/blocked_range.h>
#include "vdbrad/core/Constants.h"
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace vdbrad {
namespace test {

/// Fractions of the entering beam power; the standard errors are zero for deterministic methods.
struct SlabResult
{
    double reflectance = 0, transmittance = 0, absorptance = 0, directTransmittance = 0;
    double reflectanceStderr = 0, transmittanceStderr = 0, absorptanceStderr = 0;
    /// Absorbed by the ground under a slab or a voxel medium (see the file header); 0 where there
    /// is none (box).
    double groundAbsorptance = 0, groundAbsorptanceStderr = 0;
};

/// A box result: the slab fractions plus where the power went. Faces are numbered
/// 0: x = 0, 1: x = X, 2: y = 0 (bottom), 3: y = Y (top), 4: z = 0, 5: z = Z.
struct BoxResult : SlabResult
{
    /// F0 times the box's area projected onto the plane normal to the beam (power units).
    double incidentPower = 0;
    /// Fraction of the entering power that leaves through each face (sums to R + T).
    std::array<double, 6> faceFraction{};
};

/// Homogeneous infinite slab of vertical optical thickness tau, lit from above.
struct SlabProblem
{
    double tau = 1;     ///< vertical optical thickness, >= 0
    double omega0 = 1;  ///< single-scattering albedo, in [0, 1]
    double g = 0;       ///< Henyey-Greenstein asymmetry, in (-1, 1); 0 is isotropic
    double mu0 = 1;     ///< cosine of the solar zenith angle, in (0, 1]
    double groundAlbedo = 0;  ///< Lambertian ground under the slab, in [0, 1]; 0 is black
    /// A tabulated phase function instead of g (adding-doubling only): its Legendre
    /// coefficients chi_0 = 1, chi_1, ..., chi_L (Mie, e.g. cloud C.1 with L = 299).
    std::vector<double> legendre{};
};

/// Homogeneous box [0,X]x[0,Y]x[0,Z] (world units, y up) with open boundaries.
struct BoxProblem
{
    double sizeX = 1, sizeY = 1, sizeZ = 1;  ///< > 0, world units
    double sigma = 1;      ///< extinction coefficient per world unit, >= 0
    double omega0 = 1;     ///< single-scattering albedo, in [0, 1]
    double g = 0;          ///< Henyey-Greenstein asymmetry, in (-1, 1)
    double theta0 = 0;     ///< solar zenith angle in degrees, in [0, 90)
    double phi0 = 0;       ///< solar azimuth in degrees (from +x towards +z)
    double F0 = 1;         ///< beam irradiance on a plane normal to the beam, > 0
};

/// How many photons to trace, from which seed, and whether chunks run under TBB.
struct MonteCarloRun
{
    uint64_t photons = 100000;  ///< >= 1
    uint64_t seed = 1;
    bool threaded = true;       ///< false runs the same chunks serially (same result)
};

/// Photons per independently seeded chunk; part of the definition of a seeded result.
constexpr uint64_t kPhotonsPerChunk = 4096;


// ---- random numbers ------------------------------------------------------------------------

/// xoshiro256** (Blackman & Vigna 2018), seeded through splitmix64. Written out rather than
/// std::mt19937 + std::uniform_real_distribution because the standard leaves the distribution's
/// algorithm to the library, and a reference must give the same numbers everywhere.
class ReferenceRng
{
public:
    explicit ReferenceRng(uint64_t seed)
    {
        uint64_t x = seed;
        for (uint64_t& s : mState) s = splitMix64(x);
    }

    static uint64_t splitMix64(uint64_t& x)
    {
        uint64_t z = (x += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }

    uint64_t next()
    {
        const uint64_t result = rotl(mState[1] * 5, 7) * 9;
        const uint64_t t = mState[1] << 17;
        mState[2] ^= mState[0];
        mState[3] ^= mState[1];
        mState[1] ^= mState[2];
        mState[0] ^= mState[3];
        mState[2] ^= t;
        mState[3] = rotl(mState[3], 45);
        return result;
    }

    /// Uniform in the open interval (0, 1): 53-bit midpoints, so -log(u) is finite and positive.
    double open01() { return (double(next() >> 11) + 0.5) * 0x1.0p-53; }

private:
    static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
    uint64_t mState[4];
};

// ---- phase function ------------------------------------------------------------------------

/// @brief Cosine of the scattering angle for the Henyey-Greenstein phase function, by inversion
/// of its CDF at @a u in [0, 1] (u = 0 gives -1, u = 1 gives +1).
/// @details The textbook inverse, mu = (1 + g^2 - ((1 - g^2) / (1 + g xi))^2) / (2g) with
/// xi = 2u - 1, divides by g and loses all digits as g -> 0. Multiplying out over the common
/// denominator (1 + g xi)^2 gives the same function without the division:
///     mu = [xi + g (3 + xi^2 - g^2 + 2 g xi + g^2 xi^2) / 2] / (1 + g xi)^2,
/// which is exactly xi (isotropic) at g = 0, +-1 at xi = +-1 (to rounding), and for |g| -> 1 has
/// only the conditioning of the distribution itself. Clamped against rounding.
inline double
sampleHenyeyGreenstein(double g, double u)
{
    const double xi = 2.0 * u - 1.0;
    const double den = 1.0 + g * xi;
    const double num = xi + 0.5 * g * (3.0 + xi * xi - g * g + 2.0 * g * xi + g * g * xi * xi);
    return std::min(1.0, std::max(-1.0, num / (den * den)));
}

/// Henyey-Greenstein CDF in mu = cos(scattering angle): P(cos Th <= mu), for checking the sampler.
/// F(mu) = (1 - g^2) / (2g) [1 / sqrt(1 + g^2 - 2 g mu) - 1 / (1 + g)], (1 + mu) / 2 at g = 0.
inline double
henyeyGreensteinCdf(double g, double mu)
{
    if (g == 0.0) return 0.5 * (1.0 + mu);
    const double inner = 1.0 / std::sqrt(1.0 + g * g - 2.0 * g * mu) - 1.0 / (1.0 + g);
    return (1.0 - g * g) / (2.0 * g) * inner;
}

namespace detail {

struct Vec3
{
    double x, y, z;
};

inline Vec3 operator*(double s, const Vec3& v) { return {s * v.x, s * v.y, s * v.z}; }
inline Vec3 operator+(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }

inline Vec3
normalized(const Vec3& v)
{
    const double inv = 1.0 / std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
    return inv * v;
}

/// New direction at angle acos(mu) from @a d, azimuth 2 pi u about it. The frame is the branchless
/// orthonormal basis of Duff et al. (2017), "Building an orthonormal basis, revisited", JCGT 6(1).
/// Renormalised so that rounding cannot accumulate over thousands of scatterings.
inline Vec3
scatter(const Vec3& d, double mu, double u)
{
    const double sign = std::copysign(1.0, d.z);
    const double a = -1.0 / (sign + d.z);
    const double b = d.x * d.y * a;
    const Vec3 b1{1.0 + sign * d.x * d.x * a, sign * b, -sign * d.x};
    const Vec3 b2{b, sign + d.y * d.y * a, -d.y};
    const double sinTheta = std::sqrt(std::max(0.0, 1.0 - mu * mu));
    const double phi = 2.0 * kPi * u;
    return normalized((sinTheta * std::cos(phi)) * b1 + (sinTheta * std::sin(phi)) * b2 + mu * d);
}

/// Whole-photon outcomes (reflected, transmitted, absorbed: exactly one per photon; transmitted
/// means absorbed by the ground when there is one) and arrivals at the ground y = 0 (box: the
/// bottom face; an open voxel medium adds its downward exits through the sides, so that arrivals
/// is the transmittance count), which a photon can make several times over a reflecting ground.
/// arrivalsSq is the sum over photons of (arrivals per photon)^2, for the sample variance.
struct Tally
{
    uint64_t reflected = 0, transmitted = 0, direct = 0, absorbed = 0;
    uint64_t arrivals = 0, arrivalsSq = 0;
    std::array<uint64_t, 6> face{};

    Tally& operator+=(const Tally& o)
    {
        reflected += o.reflected;
        transmitted += o.transmitted;
        direct += o.direct;
        absorbed += o.absorbed;
        arrivals += o.arrivals;
        arrivalsSq += o.arrivalsSq;
        for (int f = 0; f < 6; ++f) face[f] += o.face[f];
        return *this;
    }
};

/// Cosine-weighted (Lambertian) upward direction: mu = sqrt(u1), azimuth 2 pi u2.
inline Vec3
lambertianUp(ReferenceRng& rng)
{
    const double u1 = rng.open01(), phi = 2.0 * kPi * rng.open01();
    const double s = std::sqrt(1.0 - u1);
    return {s * std::cos(phi), std::sqrt(u1), s * std::sin(phi)};
}

/// Counts one more arrival at the ground for a photon that has now arrived @a k times.
inline void
countArrival(uint64_t k, Tally& tally)
{
    ++tally.arrivals;
    tally.arrivalsSq += 2 * k - 1;  // k^2 - (k - 1)^2: the photon's k^2 builds up exactly
}

/// A tentative collision of delta tracking at extinction @a sigmaMax where the medium's is
/// @a sigmaHere: null (the photon flies on), absorbed, or scattered (@a dir turned by
/// Henyey-Greenstein g). Draws in this order: the real-collision test, the absorption test, the
/// scattering angle and azimuth (the references' seeded results depend on it).
enum class Collision { Null, Absorbed, Scattered };
inline Collision
deltaCollision(ReferenceRng& rng, double sigmaHere, double sigmaMax, double omega0, double g,
    Vec3& dir)
{
    if (!(rng.open01() * sigmaMax < sigmaHere)) return Collision::Null;
    if (!(rng.open01() < omega0)) return Collision::Absorbed;
    dir = scatter(dir, sampleHenyeyGreenstein(g, rng.open01()), rng.open01());
    return Collision::Scattered;
}

/// One photon from @a pos along @a dir until it escapes or is absorbed. @a exit(pos, dir, face)
/// returns the distance to the boundary along dir (infinite if none) and sets the face there.
/// Leaving through face 2 (y = 0) is an arrival at the ground, which reflects it with probability
/// @a groundAlbedo (Lambertian); 0 draws no extra random number, so the box is unchanged.
template<typename ExitT>
inline void
tracePhoton(Vec3 pos, Vec3 dir, double sigma, double omega0, double g, const ExitT& exit,
    ReferenceRng& rng, Tally& tally, double groundAlbedo = 0.0)
{
    uint64_t arrivals = 0;
    // scattered: by the medium or the ground, so only a first arrival can count as direct.
    for (bool scattered = false;; scattered = true) {
        int face = -1;
        const double toExit = exit(pos, dir, face);
        // Exponential free path; sigma = 0 gives +inf, which always escapes.
        const double path = -std::log(rng.open01()) / sigma;
        if (path >= toExit) {
            if (dir.y > 0.0) {
                ++tally.reflected;
            } else {
                if (!scattered) ++tally.direct;
                if (face == 2) {
                    countArrival(++arrivals, tally);
                    if (groundAlbedo > 0.0 && rng.open01() < groundAlbedo) {
                        pos = pos + toExit * dir;
                        pos.y = 0.0;
                        dir = lambertianUp(rng);
                        continue;
                    }
                }
                ++tally.transmitted;
            }
            ++tally.face[face];
            return;
        }
        pos = pos + path * dir;
        // Analogue absorption: u in (0,1), so omega0 = 1 always scatters and 0 never does.
        if (!(rng.open01() < omega0)) {
            ++tally.absorbed;
            return;
        }
        const double mu = sampleHenyeyGreenstein(g, rng.open01());
        dir = scatter(dir, mu, rng.open01());
    }
}

/// Runs @a photons photons in fixed, independently seeded chunks; @a launch(rng, tally) traces one.
template<typename LaunchT>
inline Tally
runChunks(const MonteCarloRun& run, const LaunchT& launch)
{
    const uint64_t chunks = (run.photons + kPhotonsPerChunk - 1) / kPhotonsPerChunk;
    auto runRange = [&](uint64_t begin, uint64_t end, Tally tally) {
        for (uint64_t c = begin; c < end; ++c) {
            // Each chunk's stream starts from a hash of (seed, chunk), independent of scheduling.
            uint64_t key = run.seed;
            uint64_t state = ReferenceRng::splitMix64(key) ^ (c * 0xD1B54A32D192ED03ull);
            ReferenceRng rng(ReferenceRng::splitMix64(state));
            const uint64_t n = std::min(kPhotonsPerChunk, run.photons - c * kPhotonsPerChunk);
            for (uint64_t i = 0; i < n; ++i) launch(rng, tally);
        }
        return tally;
    };
    if (!run.threaded) return runRange(0, chunks, Tally());
    return tbb::parallel_reduce(
        tbb::blocked_range<uint64_t>(0, chunks, 1), Tally(),
        [&](const tbb::blocked_range<uint64_t>& r, Tally t) {
            return runRange(r.begin(), r.end(), t);
        },
        [](Tally a, const Tally& b) { return a += b; });
}

/// The fractions of a tally; @a ground: the slab problems, where transmittance counts arrivals at
/// the ground and the ground absorbs what the tally calls transmitted.
inline void
fillFractions(const Tally& t, uint64_t photons, SlabResult& r, bool ground = false)
{
    const double n = double(photons);
    auto stderrOf = [n](double p) { return std::sqrt(std::max(0.0, p * (1.0 - p)) / n); };
    r.reflectance = double(t.reflected) / n;
    r.transmittance = double(t.transmitted) / n;
    r.absorptance = double(t.absorbed) / n;
    r.directTransmittance = double(t.direct) / n;
    r.reflectanceStderr = stderrOf(r.reflectance);
    r.transmittanceStderr = stderrOf(r.transmittance);
    r.absorptanceStderr = stderrOf(r.absorptance);
    if (!ground) return;
    r.groundAbsorptance = r.transmittance;
    r.groundAbsorptanceStderr = r.transmittanceStderr;
    // Over a black ground arrivals == transmitted, so these are the same bits as without one.
    r.transmittance = double(t.arrivals) / n;
    if (t.arrivalsSq == t.arrivals) {
        r.transmittanceStderr = stderrOf(r.transmittance);  // no photon arrived twice: 0/1
    } else {
        // Arrivals per photon are a count, not a 0/1 outcome: the sample variance of that count.
        const double m = r.transmittance;
        r.transmittanceStderr = std::sqrt(std::max(0.0, double(t.arrivalsSq) / n - m * m) / n);
    }
}

inline void
checkGroundAlbedo(double rho)
{
    if (!(rho >= 0.0 && rho <= 1.0)) {
        throw std::invalid_argument("groundAlbedo must be in [0,1], got " + std::to_string(rho));
    }
}

inline void
checkMedium(double omega0, double g)
{
    if (!(omega0 >= 0.0 && omega0 <= 1.0)) {
        throw std::invalid_argument("omega0 must be in [0,1], got " + std::to_string(omega0));
    }
    if (!(g > -1.0 && g < 1.0)) {
        throw std::invalid_argument("g must be in (-1,1), got " + std::to_string(g));
    }
}

inline void
checkRun(const MonteCarloRun& run)
{
    if (run.photons < 1) throw std::invalid_argument("photons must be >= 1");
}

} // namespace detail

// ---- Monte Carlo ---------------------------------------------------------------------------

/// @brief Photon Monte Carlo for a homogeneous plane-parallel slab (see the file header).
/// @details Works in optical units: height h in [0, tau], unit extinction. The photon enters at
/// the top moving along (sqrt(1 - mu0^2), -mu0, 0); the horizontal position never matters. A
/// photon reaching the ground is reflected (Lambertian) with probability p.groundAlbedo, else
/// absorbed there; see the file header for what the fractions mean then.
/// @throw std::invalid_argument for parameters outside their ranges.
inline SlabResult
slabMonteCarlo(const SlabProblem& p, const MonteCarloRun& run = MonteCarloRun())
{
    detail::checkMedium(p.omega0, p.g);
    detail::checkRun(run);
    detail::checkGroundAlbedo(p.groundAlbedo);
    if (!(p.tau >= 0.0 && std::isfinite(p.tau))) {
        throw std::invalid_argument("tau must be finite and >= 0, got " + std::to_string(p.tau));
    }
    if (!(p.mu0 > 0.0 && p.mu0 <= 1.0)) {
        throw std::invalid_argument("mu0 must be in (0,1], got " + std::to_string(p.mu0));
    }
    const double tau = p.tau;
    auto exit = [tau](const detail::Vec3& pos, const detail::Vec3& dir, int& face) {
        face = dir.y > 0.0 ? 3 : 2;
        if (dir.y < 0.0) return pos.y / -dir.y;
        if (dir.y > 0.0) return (tau - pos.y) / dir.y;
        return std::numeric_limits<double>::infinity();
    };
    const detail::Vec3 start{0.0, tau, 0.0};
    const detail::Vec3 dir0{std::sqrt(1.0 - p.mu0 * p.mu0), -p.mu0, 0.0};
    const detail::Tally tally = detail::runChunks(run, [&](ReferenceRng& rng, detail::Tally& t) {
        detail::tracePhoton(start, dir0, 1.0, p.omega0, p.g, exit, rng, t, p.groundAlbedo);
    });
    SlabResult r;
    detail::fillFractions(tally, run.photons, r, true);
    return r;
}

/// Sun direction (pointing to the sun) for zenith @a theta0 and azimuth @a phi0 in degrees.
inline std::array<double, 3>
sunDirection(double theta0, double phi0)
{
    const double th = theta0 * kPi / 180.0, ph = phi0 * kPi / 180.0;
    return {std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph)};
}

/// Areas of the box's faces projected onto the plane normal to the beam, by face (zero for faces
/// turned away from the sun); their sum times F0 is the power entering the box.
inline std::array<double, 6>
boxProjectedFaceAreas(const BoxProblem& p)
{
    const std::array<double, 3> s = sunDirection(p.theta0, p.phi0);
    const double ax = p.sizeY * p.sizeZ, ay = p.sizeX * p.sizeZ, az = p.sizeX * p.sizeY;
    return {ax * std::max(0.0, -s[0]), ax * std::max(0.0, s[0]),
        ay * std::max(0.0, -s[1]), ay * std::max(0.0, s[1]),
        az * std::max(0.0, -s[2]), az * std::max(0.0, s[2])};
}

namespace detail {

/// Entry points uniform over a box's projection onto the plane normal to the beam: a lit face
/// with probability proportional to its projected area, then a point uniform on it (three
/// draws, in this order: the references' seeded results depend on it).
struct BoxEntry
{
    std::array<double, 6> area{}, cumulative{};
    double total = 0.0;
    int lastLit = 0;
    double hi[3];

    BoxEntry(const BoxProblem& p)
        : area(boxProjectedFaceAreas(p)), hi{p.sizeX, p.sizeY, p.sizeZ}
    {
        for (int f = 0; f < 6; ++f) {
            cumulative[f] = (total += area[f]);
            if (area[f] > 0.0) lastLit = f;
        }
    }

    Vec3 sample(ReferenceRng& rng) const
    {
        // The first lit face whose cumulative area exceeds the pick; the last lit face if
        // rounding pushes the pick up to the total.
        const double pick = rng.open01() * total;
        int f = lastLit;
        for (int k = 0; k < 6; ++k) {
            if (area[k] > 0.0 && pick < cumulative[k]) {
                f = k;
                break;
            }
        }
        const int axis = f / 2;
        double q[3];
        q[axis] = (f % 2) ? hi[axis] : 0.0;
        q[(axis + 1) % 3] = rng.open01() * hi[(axis + 1) % 3];
        q[(axis + 2) % 3] = rng.open01() * hi[(axis + 2) % 3];
        return {q[0], q[1], q[2]};
    }
};

} // namespace detail

/// @brief Photon Monte Carlo for a homogeneous box with open boundaries, lit by a parallel beam.
/// @details Entry points are uniform over the box's projection onto the plane normal to the beam:
/// a lit face is chosen with probability proportional to its projected area, then a point uniform
/// on it. Fractions are of the entering power, BoxResult::incidentPower.
/// @throw std::invalid_argument for parameters outside their ranges.
inline BoxResult
boxMonteCarlo(const BoxProblem& p, const MonteCarloRun& run = MonteCarloRun())
{
    detail::checkMedium(p.omega0, p.g);
    detail::checkRun(run);
    const double volume = p.sizeX * p.sizeY * p.sizeZ;
    if (!(p.sizeX > 0 && p.sizeY > 0 && p.sizeZ > 0 && std::isfinite(volume))) {
        throw std::invalid_argument("box sizes must be finite and > 0");
    }
    if (!(p.sigma >= 0.0 && std::isfinite(p.sigma))) {
        throw std::invalid_argument(
            "sigma must be finite and >= 0, got " + std::to_string(p.sigma));
    }
    if (!(p.theta0 >= 0.0 && p.theta0 < 90.0) || !std::isfinite(p.phi0)) {
        throw std::invalid_argument("theta0 must be in [0,90) degrees, got "
            + std::to_string(p.theta0));
    }
    if (!(p.F0 > 0.0 && std::isfinite(p.F0))) {
        throw std::invalid_argument("F0 must be finite and > 0");
    }
    const detail::BoxEntry entry(p);
    const double hi[3] = {p.sizeX, p.sizeY, p.sizeZ};
    auto exit = [&hi](const detail::Vec3& pos, const detail::Vec3& dir, int& face) {
        // Distance to the nearest face ahead, from inside (slab method, exit side only).
        const double q[3] = {pos.x, pos.y, pos.z}, d[3] = {dir.x, dir.y, dir.z};
        double best = std::numeric_limits<double>::infinity();
        for (int a = 0; a < 3; ++a) {
            if (d[a] == 0.0) continue;
            const double t = d[a] > 0.0 ? (hi[a] - q[a]) / d[a] : -q[a] / d[a];
            if (t < best) {
                best = t;
                face = 2 * a + (d[a] > 0.0 ? 1 : 0);
            }
        }
        return std::max(0.0, best);  // rounding may put pos a hair outside
    };
    const std::array<double, 3> s = sunDirection(p.theta0, p.phi0);
    const detail::Vec3 dir0{-s[0], -s[1], -s[2]};
    const detail::Tally tally = detail::runChunks(run, [&](ReferenceRng& rng, detail::Tally& t) {
        detail::tracePhoton(entry.sample(rng), dir0, p.sigma, p.omega0, p.g, exit, rng, t);
    });
    BoxResult r;
    detail::fillFractions(tally, run.photons, r);
    r.incidentPower = p.F0 * entry.total;
    for (int f = 0; f < 6; ++f) r.faceFraction[f] = double(tally.face[f]) / double(run.photons);
    return r;
}

/// Periodic columns along x (the I3RC step cloud is 32 of them): column c spans
/// [c w, (c + 1) w) with w = width / columns and has vertical optical thickness columnTau[c] over
/// the height; the medium is uniform along z and repeats along x with period width.
struct ColumnsProblem
{
    double width = 0.5, height = 0.25;   ///< world units, > 0
    std::vector<double> columnTau;       ///< per column, >= 0, at least one
    double omega0 = 1, g = 0;
    double theta0 = 0, phi0 = 0;         ///< sun, degrees (azimuth from +x towards +z)
    double groundAlbedo = 0;             ///< Lambertian ground at y = 0, in [0, 1]; 0 is black
};

/// @brief Photon Monte Carlo for periodic columns (ColumnsProblem), lit from above.
/// @details Photons enter the top uniformly along x (so fractions are of the power F0 cos theta0
/// per unit horizontal area) and travel along -sun. Free paths by delta tracking (Woodcock):
/// tentative steps at the largest extinction, a collision real with probability sigma(x) /
/// sigma_max, which samples the exact free path through piecewise-constant columns without
/// crossing them one by one. direct counts transmitted photons with no real collision. The
/// ground (p.groundAlbedo) reflects a photon where it lands, as in slabMonteCarlo.
/// @throw std::invalid_argument for parameters outside their ranges.
inline SlabResult
columnsMonteCarlo(const ColumnsProblem& p, const MonteCarloRun& run = MonteCarloRun())
{
    detail::checkMedium(p.omega0, p.g);
    detail::checkRun(run);
    detail::checkGroundAlbedo(p.groundAlbedo);
    if (!(p.width > 0.0 && p.height > 0.0 && std::isfinite(p.width * p.height))
        || p.columnTau.empty()) {
        throw std::invalid_argument("columns need a finite width and height > 0 and a column");
    }
    if (!(p.theta0 >= 0.0 && p.theta0 < 90.0) || !std::isfinite(p.phi0)) {
        throw std::invalid_argument("theta0 must be in [0,90) degrees, got "
            + std::to_string(p.theta0));
    }
    const size_t n = p.columnTau.size();
    std::vector<double> sigma(n);
    double sigmaMax = 0.0;
    for (size_t c = 0; c < n; ++c) {
        if (!(p.columnTau[c] >= 0.0 && std::isfinite(p.columnTau[c]))) {
            throw std::invalid_argument("column optical thickness must be finite and >= 0");
        }
        sigma[c] = p.columnTau[c] / p.height;
        sigmaMax = std::max(sigmaMax, sigma[c]);
    }
    const std::array<double, 3> s = sunDirection(p.theta0, p.phi0);
    const detail::Vec3 dir0{-s[0], -s[1], -s[2]};
    const double W = p.width, H = p.height, w = W / double(n);
    const detail::Tally tally = detail::runChunks(run, [&](ReferenceRng& rng, detail::Tally& t) {
        detail::Vec3 pos{rng.open01() * W, H, 0.0}, dir = dir0;
        bool scattered = false;  // by a real collision or the ground
        uint64_t arrivals = 0;
        for (;;) {
            // sigma_max = 0 gives an infinite step: the photon leaves.
            const double step = -std::log(rng.open01()) / sigmaMax;
            const double y = pos.y + step * dir.y;
            if (!(y > 0.0 && y < H)) {
                if (dir.y > 0.0) {
                    ++t.reflected;
                    return;
                }
                if (!scattered) ++t.direct;
                detail::countArrival(++arrivals, t);
                if (p.groundAlbedo > 0.0 && rng.open01() < p.groundAlbedo) {
                    // Land where the path meets y = 0 (the horizontal position matters here).
                    pos = pos + (pos.y / -dir.y) * dir;
                    pos.x -= W * std::floor(pos.x / W);
                    pos.y = 0.0;
                    dir = detail::lambertianUp(rng);
                    scattered = true;
                    continue;
                }
                ++t.transmitted;
                return;
            }
            pos = pos + step * dir;
            pos.x -= W * std::floor(pos.x / W);
            const size_t c = std::min(n - 1, size_t(pos.x / w));
            const detail::Collision hit =
                detail::deltaCollision(rng, sigma[c], sigmaMax, p.omega0, p.g, dir);
            if (hit == detail::Collision::Absorbed) {
                ++t.absorbed;
                return;
            }
            if (hit == detail::Collision::Scattered) scattered = true;
        }
    });
    SlabResult r;
    detail::fillFractions(tally, run.photons, r, true);
    return r;
}

/// A medium of voxels: extinction per world unit on an nx x ny x nz lattice of cubes of side h
/// (world box [0, nx h) x [0, ny h) x [0, nz h)), cell (i, j, k) at index i + nx (j + ny k); zero
/// where there is no medium. Albedo and phase uniform.
struct VoxelMediumProblem
{
    int nx = 1, ny = 1, nz = 1;  ///< cells per axis, >= 1
    double h = 1;                ///< cell side, world units, > 0
    std::vector<double> sigma;   ///< nx*ny*nz extinction coefficients per world unit, >= 0, finite
    double omega0 = 1, g = 0;
    double theta0 = 0, phi0 = 0;  ///< sun, degrees (azimuth from +x towards +z)
    bool periodic = false;        ///< wrap x and z (period nx h, nz h)
    /// Lambertian ground at y = 0, in [0, 1]; 0 is black. Open: under the box's footprint only.
    double groundAlbedo = 0;
};

/// @brief Photon Monte Carlo for a voxel medium (VoxelMediumProblem), e.g. a 3D cloud.
/// @details Open (p.periodic false): photons enter uniformly over the box's projection onto the
/// plane normal to the beam, as in boxMonteCarlo, and escape wherever they leave the box;
/// incidentPower is that projected area (F0 = 1) and faceFraction says where the power left.
/// Periodic: photons enter uniformly over the top face, x and z wrap, and they leave through
/// the top or the bottom only; incidentPower = cos(theta0) nx h nz h. Free paths by delta
/// tracking (Woodcock), as in columnsMonteCarlo: steps at sigma_max = max sigma, a collision real
/// with probability sigma(cell) / sigma_max, the cell floor(pos / h) clamped to the lattice.
/// This samples the exact free path through piecewise-constant voxels.
///
/// The ground: a photon leaving through the bottom face y = 0 lands on it (open: the bottom face
/// is the footprint, so every such photon is under the box) and is reflected into a
/// cosine-weighted upward direction with probability p.groundAlbedo, else absorbed there; 0
/// draws nothing extra. As for the slab, transmittance counts every downward crossing
/// (arrivals at the ground, and open: downward exits through the sides) per entering photon,
/// groundAbsorptance = faceFraction[2] is what the ground absorbs (all that reaches it when it is
/// black), directTransmittance the unscattered first crossings. So R + A + groundAbsorptance = 1
/// when periodic, and A + sum(faceFraction) = 1 always, in counts; with groundAlbedo = 0,
/// R + T + A = 1 too.
/// @throw std::invalid_argument for parameters outside their ranges.
inline BoxResult
voxelMediumMonteCarlo(const VoxelMediumProblem& p, const MonteCarloRun& run = MonteCarloRun())
{
    detail::checkMedium(p.omega0, p.g);
    detail::checkRun(run);
    detail::checkGroundAlbedo(p.groundAlbedo);
    if (!(p.nx >= 1 && p.ny >= 1 && p.nz >= 1)) {
        throw std::invalid_argument("a voxel medium needs at least one cell along each axis");
    }
    const double X = p.nx * p.h, Y = p.ny * p.h, Z = p.nz * p.h;
    if (!(p.h > 0.0 && std::isfinite(X * Y * Z))) {
        throw std::invalid_argument("voxel size h must be > 0 and the box finite");
    }
    const size_t cells = size_t(p.nx) * size_t(p.ny) * size_t(p.nz);
    if (p.sigma.size() != cells) {
        throw std::invalid_argument("sigma must have nx*ny*nz = " + std::to_string(cells)
            + " values, got " + std::to_string(p.sigma.size()));
    }
    double sigmaMax = 0.0;
    for (double s : p.sigma) {
        if (!(s >= 0.0 && std::isfinite(s))) {
            throw std::invalid_argument("sigma must be finite and >= 0, got " + std::to_string(s));
        }
        sigmaMax = std::max(sigmaMax, s);
    }
    if (!(p.theta0 >= 0.0 && p.theta0 < 90.0) || !std::isfinite(p.phi0)) {
        throw std::invalid_argument("theta0 must be in [0,90) degrees, got "
            + std::to_string(p.theta0));
    }

    // Open entry: boxMonteCarlo's, on the same box (so incidentPower is the same bits).
    BoxProblem box;
    box.sizeX = X, box.sizeY = Y, box.sizeZ = Z, box.theta0 = p.theta0, box.phi0 = p.phi0;
    const detail::BoxEntry entry(box);
    const double hi[3] = {X, Y, Z};
    const bool periodic = p.periodic;
    auto exit = [&hi, periodic](const detail::Vec3& pos, const detail::Vec3& dir, int& face) {
        // Distance to the nearest face ahead, from inside; periodic: the top and bottom only.
        const double q[3] = {pos.x, pos.y, pos.z}, d[3] = {dir.x, dir.y, dir.z};
        double best = std::numeric_limits<double>::infinity();
        face = d[1] > 0.0 ? 3 : 2;
        for (int a = periodic ? 1 : 0; a < (periodic ? 2 : 3); ++a) {
            if (d[a] == 0.0) continue;
            const double t = d[a] > 0.0 ? (hi[a] - q[a]) / d[a] : -q[a] / d[a];
            if (t < best) {
                best = t;
                face = 2 * a + (d[a] > 0.0 ? 1 : 0);
            }
        }
        return std::max(0.0, best);  // rounding may put pos a hair outside
    };
    auto wrap = [X, Z](detail::Vec3& pos) {
        pos.x -= X * std::floor(pos.x / X);
        pos.z -= Z * std::floor(pos.z / Z);
    };
    auto cellIndex = [&p](double v, int n) {
        const double c = std::floor(v / p.h);  // clamped: rounding may leave pos on the far side
        return c <= 0.0 ? size_t(0) : c >= double(n - 1) ? size_t(n - 1) : size_t(c);
    };
    auto sigmaAt = [&](const detail::Vec3& pos) {
        return p.sigma[cellIndex(pos.x, p.nx)
            + size_t(p.nx) * (cellIndex(pos.y, p.ny) + size_t(p.ny) * cellIndex(pos.z, p.nz))];
    };

    const std::array<double, 3> s = sunDirection(p.theta0, p.phi0);
    const detail::Vec3 dir0{-s[0], -s[1], -s[2]};
    const detail::Tally tally = detail::runChunks(run, [&](ReferenceRng& rng, detail::Tally& t) {
        detail::Vec3 pos;
        if (periodic) {
            const double x = rng.open01() * X;
            pos = {x, Y, rng.open01() * Z};
        } else {
            pos = entry.sample(rng);
        }
        detail::Vec3 dir = dir0;
        bool scattered = false;  // by a real collision or the ground
        uint64_t arrivals = 0;
        for (;;) {
            int face = -1;
            const double toExit = exit(pos, dir, face);
            // sigma_max = 0 gives an infinite step: the photon leaves.
            const double step = -std::log(rng.open01()) / sigmaMax;
            if (step >= toExit) {
                if (dir.y > 0.0) {
                    ++t.reflected;
                    ++t.face[face];
                    return;
                }
                if (!scattered) ++t.direct;
                detail::countArrival(++arrivals, t);
                if (face == 2 && p.groundAlbedo > 0.0 && rng.open01() < p.groundAlbedo) {
                    pos = pos + toExit * dir;
                    pos.y = 0.0;
                    if (periodic) wrap(pos);
                    dir = detail::lambertianUp(rng);
                    scattered = true;
                    continue;
                }
                ++t.transmitted;
                ++t.face[face];
                return;
            }
            pos = pos + step * dir;
            if (periodic) wrap(pos);
            const detail::Collision hit =
                detail::deltaCollision(rng, sigmaAt(pos), sigmaMax, p.omega0, p.g, dir);
            if (hit == detail::Collision::Absorbed) {
                ++t.absorbed;
                return;
            }
            if (hit == detail::Collision::Scattered) scattered = true;
        }
    });
    BoxResult r;
    // Transmittance counts crossings (a count per photon over a reflecting ground).
    detail::fillFractions(tally, run.photons, r, true);
    const double n = double(run.photons);
    for (int f = 0; f < 6; ++f) r.faceFraction[f] = double(tally.face[f]) / n;
    // Open, the sides' downward exits are transmitted but not absorbed by the ground.
    r.groundAbsorptance = r.faceFraction[2];
    r.groundAbsorptanceStderr =
        std::sqrt(std::max(0.0, r.groundAbsorptance * (1.0 - r.groundAbsorptance)) / n);
    r.incidentPower = periodic ? s[1] * X * Z : entry.total;
    return r;
}

// ---- delta-Eddington -----------------------------------------------------------------------

namespace detail {

/// Eddington two-stream albedo and total transmittance of a slab over a black surface.
/// Derivation (Shettle & Weinman 1970; coefficients as tabulated by Meador & Weaver 1980,
/// J. Atmos. Sci. 37, 630, Table 1). With I(tau, mu) = I0 + mu I1 and the phase function
/// truncated to 1 + 3 g cos Th, the zeroth and first angular moments of the transfer equation give,
/// for the hemispheric fluxes F+ (up) and F- (down), tau increasing downward, unit beam irradiance:
///     dF+/dtau =  g1 F+ - g2 F- - omega0 g3 exp(-tau/mu0)
///     dF-/dtau =  g2 F+ - g1 F- + omega0 g4 exp(-tau/mu0)
///     g1 = (7 - omega0 (4 + 3g)) / 4,  g2 = -(1 - omega0 (4 - 3g)) / 4,
///     g3 = (2 - 3 g mu0) / 4,          g4 = 1 - g3,
/// with F-(0) = 0 and F+(tau*) = 0. Writing Y = (F+, F-), Y' = M Y + S e^(-tau/mu0): M^2 = k^2 I,
/// k^2 = g1^2 - g2^2 = 3 (1 - omega0)(1 - omega0 g), so exp(M t) = cosh(kt) I + sinh(kt)/k M,
/// which is analytic at k = 0: the conservative case needs no separate formula. A particular
/// solution is P e^(-tau/mu0) with (M + I/mu0) P = -S. Imposing F+(tau*) = 0 on the forward
/// solution and F-(0) = 0 on the backward one (so that no term grows like e^(k tau*)) gives
///     F+(0)    = P+ - (P+ e sech + g2 t P-) / (1 + g1 t)
///     F-(tau*) = P- e - (P- sech + g2 t P+ e) / (1 + g1 t)
/// with e = exp(-tau*/mu0), sech = 1/cosh(k tau*), t = tanh(k tau*)/k (-> tau* as k -> 0).
/// Albedo = F+(0)/mu0; transmittance = F-(tau*)/mu0 + e. At the resonance k mu0 = 1 the
/// particular solution is singular; there the result is the mean of mu0 (1 +- 2e-5), which is
/// the limit to O(1e-10).
inline std::pair<double, double>
eddingtonSlab(double tau, double omega0, double g, double mu0)
{
    const double g1 = (7.0 - omega0 * (4.0 + 3.0 * g)) / 4.0;
    const double g2 = -(1.0 - omega0 * (4.0 - 3.0 * g)) / 4.0;
    // g1 - g2 = 2 (1 - omega0) exactly, so k = 0 exactly when omega0 = 1.
    const double k = std::sqrt(std::max(0.0, 2.0 * (1.0 - omega0) * (g1 + g2)));
    auto solve = [&](double m0) {
        const double g3 = (2.0 - 3.0 * g * m0) / 4.0, g4 = 1.0 - g3;
        const double det = 1.0 / (m0 * m0) - k * k;
        const double pUp = omega0 / det * ((1.0 / m0 - g1) * g3 - g2 * g4);
        const double pDown = -omega0 / det * (g2 * g3 + (g1 + 1.0 / m0) * g4);
        const double kt = k * tau;
        const double t = kt < 1e-4 ? tau * (1.0 - kt * kt / 3.0) : std::tanh(kt) / k;
        const double sech = 1.0 / std::cosh(kt);
        const double e = std::exp(-tau / m0);
        const double up0 = pUp - (pUp * e * sech + g2 * t * pDown) / (1.0 + g1 * t);
        const double downN = pDown * e - (pDown * sech + g2 * t * pUp * e) / (1.0 + g1 * t);
        return std::make_pair(up0 / m0, downN / m0 + e);
    };
    const double delta = 1e-5;
    if (std::abs(1.0 - k * mu0) >= delta) return solve(mu0);
    const auto a = solve(mu0 * (1.0 + 2.0 * delta)), b = solve(mu0 * (1.0 - 2.0 * delta));
    return {0.5 * (a.first + b.first), 0.5 * (a.second + b.second)};
}

/// Delta-M scaling with f = g^2 (Joseph, Wiscombe & Weinman 1976, J. Atmos. Sci. 33, 2452):
/// the forward peak is moved into the direct beam, tau' = (1 - omega0 f) tau,
/// omega0' = (1 - f) omega0 / (1 - omega0 f), g' = (g - f) / (1 - f) = g / (1 + g).
inline std::pair<double, double>
deltaEddingtonSlab(double tau, double omega0, double g, double mu0)
{
    checkMedium(omega0, g);
    if (!(tau >= 0.0) || !(mu0 > 0.0 && mu0 <= 1.0)) {
        throw std::invalid_argument("delta-Eddington needs tau >= 0 and mu0 in (0,1]");
    }
    const double f = g * g;
    const double tauS = (1.0 - omega0 * f) * tau;
    const double omegaS = omega0 == 1.0 ? 1.0 : (1.0 - f) * omega0 / (1.0 - omega0 * f);
    const double gS = g / (1.0 + g);
    return eddingtonSlab(tauS, omegaS, gS, mu0);
}

} // namespace detail

/// @brief Delta-Eddington plane albedo (reflectance) of a homogeneous slab over a black surface,
/// for a beam at cosine @a mu0. The two-stream solution can leave [0, 1] in extreme cases (thin,
/// strongly absorbing, grazing sun); it is not clamped.
/// @throw std::invalid_argument for omega0 outside [0,1], g outside (-1,1), tau < 0 or mu0
/// outside (0,1].
inline double
deltaEddingtonAlbedo(double tau, double omega0, double g, double mu0)
{
    return detail::deltaEddingtonSlab(tau, omega0, g, mu0).first;
}

/// Delta-Eddington total (direct + diffuse) transmittance; see deltaEddingtonAlbedo. The
/// "direct" part here is the scaled beam exp(-tau'/mu0), which includes the forward peak.
inline double
deltaEddingtonTransmittance(double tau, double omega0, double g, double mu0)
{
    return detail::deltaEddingtonSlab(tau, omega0, g, mu0).second;
}

// ---- adding-doubling -----------------------------------------------------------------------

namespace detail {

/// Gauss-Legendre nodes and weights on (0, 1), by Newton iteration on P_n.
inline void
gaussLegendre01(int n, std::vector<double>& x, std::vector<double>& w)
{
    x.assign(n, 0.0);
    w.assign(n, 0.0);
    for (int i = 0; i < n; ++i) {
        double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), dp = 0;
        for (int it = 0; it < 100; ++it) {
            double p0 = 1.0, p1 = z;
            for (int l = 2; l <= n; ++l) {
                const double p2 = ((2.0 * l - 1.0) * z * p1 - (l - 1.0) * p0) / l;
                p0 = p1;
                p1 = p2;
            }
            dp = n * (z * p1 - p0) / (z * z - 1.0);
            const double dz = p1 / dp;
            z -= dz;
            if (std::abs(dz) < 1e-16) break;
        }
        x[i] = 0.5 * (1.0 + z);
        w[i] = 1.0 / ((1.0 - z * z) * dp * dp);  // (2 / ((1-z^2) P'^2)) / 2 for (0,1)
    }
}

/// Complete elliptic integral of the second kind E(k), modulus k in [0,1), by the AGM.
inline double
ellipticE(double k)
{
    double a = 1.0, b = std::sqrt(1.0 - k * k), c = k, sum = 0.5 * c * c, pow2 = 0.5;
    for (int i = 0; i < 60 && std::abs(c) > 1e-17; ++i) {
        c = 0.5 * (a - b);
        const double an = 0.5 * (a + b);
        b = std::sqrt(a * b);
        a = an;
        pow2 *= 2.0;
        sum += pow2 * c * c;
    }
    return kPi / (2.0 * a) * (1.0 - sum);
}

/// Azimuthal mean of the HG phase function between directions with cosines mu1, mu2 (signed,
/// relative to up): (1/2pi) int p dphi. With cos Th = mu1 mu2 + s1 s2 cos phi,
/// a = 1 + g^2 - 2 g mu1 mu2 and b = |2 g s1 s2|,
///     int_0^2pi (a - b cos phi)^(-3/2) dphi = 4 E(m) / ((a - b) sqrt(a + b)), m = 2b / (a + b)
/// (Gradshteyn & Ryzhik 2.575; at b = 0 it is 2 pi / a^(3/2)).
inline double
hgAzimuthalMean(double g, double mu1, double mu2)
{
    if (g == 0.0) return 1.0;
    const double s = std::sqrt(std::max(0.0, 1.0 - mu1 * mu1) * std::max(0.0, 1.0 - mu2 * mu2));
    const double a = 1.0 + g * g - 2.0 * g * mu1 * mu2, b = std::abs(2.0 * g * s);
    const double k = std::sqrt(2.0 * b / (a + b));
    return (1.0 - g * g) * 2.0 * ellipticE(k) / (kPi * (a - b) * std::sqrt(a + b));
}

/// Azimuthal mean of the phase function sum_l (2l + 1) chi_l P_l(cos Th) between directions
/// of cosines mu1, mu2: by the addition theorem sum_l (2l + 1) chi_l P_l(mu1) P_l(mu2).
inline double
legendreAzimuthalMean(const std::vector<double>& chi, double mu1, double mu2)
{
    double sum = 0.0, a0 = 1.0, a1 = mu1, b0 = 1.0, b1 = mu2;
    for (size_t l = 0; l < chi.size(); ++l) {
        double a = 1.0, b = 1.0;
        if (l == 1) {
            a = mu1;
            b = mu2;
        } else if (l >= 2) {
            const double k = double(l);
            a = ((2.0 * k - 1.0) * mu1 * a1 - (k - 1.0) * a0) / k;
            b = ((2.0 * k - 1.0) * mu2 * b1 - (k - 1.0) * b0) / k;
            a0 = a1;
            a1 = a;
            b0 = b1;
            b1 = b;
        }
        sum += (2.0 * double(l) + 1.0) * chi[l] * a * b;
    }
    return sum;
}

/// Small dense row-major matrix helpers for the doubling.
using Matrix = std::vector<double>;

inline Matrix
matMul(const Matrix& A, const Matrix& B, int n)
{
    Matrix C(size_t(n) * n, 0.0);
    for (int i = 0; i < n; ++i) {
        for (int k = 0; k < n; ++k) {
            const double a = A[size_t(i) * n + k];
            for (int j = 0; j < n; ++j) C[size_t(i) * n + j] += a * B[size_t(k) * n + j];
        }
    }
    return C;
}

inline std::vector<double>
matVec(const Matrix& A, const std::vector<double>& v, int n)
{
    std::vector<double> r(n, 0.0);
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) r[i] += A[size_t(i) * n + j] * v[j];
    }
    return r;
}

/// Solves A X = B in place (B is n x m, row-major) by Gaussian elimination, partial pivoting.
inline void
solveInPlace(Matrix A, Matrix& B, int n, int m)
{
    for (int c = 0; c < n; ++c) {
        int piv = c;
        for (int r = c + 1; r < n; ++r) {
            if (std::abs(A[size_t(r) * n + c]) > std::abs(A[size_t(piv) * n + c])) piv = r;
        }
        if (piv != c) {
            for (int j = 0; j < n; ++j) std::swap(A[size_t(c) * n + j], A[size_t(piv) * n + j]);
            for (int j = 0; j < m; ++j) std::swap(B[size_t(c) * m + j], B[size_t(piv) * m + j]);
        }
        const double inv = 1.0 / A[size_t(c) * n + c];
        for (int r = c + 1; r < n; ++r) {
            const double f = A[size_t(r) * n + c] * inv;
            if (f == 0.0) continue;
            for (int j = c; j < n; ++j) A[size_t(r) * n + j] -= f * A[size_t(c) * n + j];
            for (int j = 0; j < m; ++j) B[size_t(r) * m + j] -= f * B[size_t(c) * m + j];
        }
    }
    for (int c = n - 1; c >= 0; --c) {
        const double inv = 1.0 / A[size_t(c) * n + c];
        for (int j = 0; j < m; ++j) {
            double v = B[size_t(c) * m + j];
            for (int k = c + 1; k < n; ++k) v -= A[size_t(c) * n + k] * B[size_t(k) * m + j];
            B[size_t(c) * m + j] = v * inv;
        }
    }
}

/// addingDoublingSlab (which see for the method) for several beams at once, of cosines @a mu0s
/// (p.mu0 is not used): the doubling of the diffuse operators, O(nodes^3) a step, is shared and
/// each beam adds O(nodes^2). A beam's arithmetic is that of a one-beam run: the same bits.
inline std::vector<SlabResult>
addingDoublingBeams(const SlabProblem& p, const std::vector<double>& mu0s, int nodes)
{
    checkMedium(p.omega0, p.g);
    if (!p.legendre.empty() && !(p.legendre[0] == 1.0)) {
        throw std::invalid_argument("adding-doubling: Legendre coefficients start with chi_0 = 1");
    }
    // The phase function's azimuthal mean: Henyey-Greenstein's closed form or the series.
    const auto phase = [&p](double mu1, double mu2) {
        return p.legendre.empty() ? hgAzimuthalMean(p.g, mu1, mu2)
                                  : legendreAzimuthalMean(p.legendre, mu1, mu2);
    };
    if (p.legendre.empty() && std::abs(p.g) > 0.95) {
        throw std::invalid_argument("adding-doubling cannot resolve a Henyey-Greenstein peak "
            "with |g| > 0.95 (got " + std::to_string(p.g) + "): use the photon Monte Carlo");
    }
    bool badMu = false;
    for (double m0 : mu0s) badMu = badMu || !(m0 > 0.0 && m0 <= 1.0);
    if (!(p.tau >= 0.0 && std::isfinite(p.tau)) || badMu || nodes < 1) {
        throw std::invalid_argument("adding-doubling needs tau >= 0, mu0 in (0,1], nodes >= 1");
    }
    const size_t beams = mu0s.size();
    std::vector<SlabResult> out(beams);
    for (size_t b = 0; b < beams; ++b) out[b].directTransmittance = std::exp(-p.tau / mu0s[b]);
    if (p.tau == 0.0) {
        for (SlabResult& o : out) o.transmittance = o.groundAbsorptance = 1.0;
        return out;
    }
    const int n = nodes;
    std::vector<double> mu, w;
    gaussLegendre01(n, mu, w);
    int doublings = 0;
    double dtau = p.tau;
    while (dtau > 1e-12) {
        dtau *= 0.5;
        ++doublings;
    }
    const double om = p.omega0;
    // D is the diffuse part of the transmission operator; the direct part E = diag(exp(-h/mu_i))
    // of a layer of thickness h is kept apart and recomputed from h. Adding O(dtau) scattering to
    // a diagonal of 1 - O(dtau) would leave the balance between attenuation and scattering to
    // the last few digits of that diagonal: with this start layer, R + T = 1 - 5e-4 (measured).
    Matrix R(size_t(n) * n), D(size_t(n) * n);
    std::vector<std::vector<double>> r(beams, std::vector<double>(n));
    std::vector<std::vector<double>> t(beams, std::vector<double>(n));
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
            const double xp = 1.0 / mu[i] + 1.0 / mu[j], xm = 1.0 / mu[i] - 1.0 / mu[j];
            const double pr = phase(mu[i], -mu[j]);
            const double pt = phase(mu[i], mu[j]);
            const double pre = om * w[j] / (2.0 * mu[i]);
            R[size_t(i) * n + j] = pre * pr * -std::expm1(-dtau * xp) / xp;
            const double tInt = xm == 0.0 ? dtau : std::expm1(dtau * xm) / xm;
            D[size_t(i) * n + j] = pre * pt * std::exp(-dtau / mu[i]) * tInt;
        }
        for (size_t b = 0; b < beams; ++b) {
            const double m0 = mu0s[b];
            const double yp = 1.0 / mu[i] + 1.0 / m0, ym = 1.0 / mu[i] - 1.0 / m0;
            const double pre = om / (4.0 * kPi * mu[i]);
            r[b][i] = pre * phase(mu[i], -m0) * -std::expm1(-dtau * yp) / yp;
            t[b][i] = pre * phase(mu[i], m0) * std::exp(-dtau / mu[i])
                * (ym == 0.0 ? dtau : std::expm1(dtau * ym) / ym);
        }
    }
    double h = dtau;
    std::vector<double> E(n);
    for (int step = 0; step < doublings; ++step) {
        for (int i = 0; i < n; ++i) E[i] = std::exp(-h / mu[i]);
        // S = (I - RR)^-1 RR = sum_{k>=1} (RR)^k: the interreflections, all terms >= 0, so
        // (I - RR)^-1 = I + S is applied without ever forming I + (something small).
        const Matrix RR = matMul(R, R, n);
        Matrix A(RR.size());
        for (size_t k = 0; k < A.size(); ++k) A[k] = -RR[k];
        for (int i = 0; i < n; ++i) A[size_t(i) * n + i] += 1.0;
        Matrix S = RR;
        solveInPlace(A, S, n, n);
        // T = E + D applied from the left (T X) and from the right (X T), and to a vector.
        auto leftT = [&](const Matrix& X) {
            Matrix Y = matMul(D, X, n);
            for (int i = 0; i < n; ++i) {
                for (int j = 0; j < n; ++j) Y[size_t(i) * n + j] += E[i] * X[size_t(i) * n + j];
            }
            return Y;
        };
        auto rightT = [&](const Matrix& X) {
            Matrix Y = matMul(X, D, n);
            for (int i = 0; i < n; ++i) {
                for (int j = 0; j < n; ++j) Y[size_t(i) * n + j] += X[size_t(i) * n + j] * E[j];
            }
            return Y;
        };
        auto applyT = [&](const std::vector<double>& x) {
            std::vector<double> y = matVec(D, x, n);
            for (int i = 0; i < n; ++i) y[i] += E[i] * x[i];
            return y;
        };
        // Beam: u = (I + S)(t + e R r), d = e r + R u, r' = r + T d, t' = e t + T u.
        for (size_t b = 0; b < beams; ++b) {
            const double e = std::exp(-h / mu0s[b]);
            std::vector<double> v = matVec(R, r[b], n);
            for (int i = 0; i < n; ++i) v[i] = t[b][i] + e * v[i];
            std::vector<double> u = matVec(S, v, n);
            for (int i = 0; i < n; ++i) u[i] += v[i];
            std::vector<double> d = matVec(R, u, n);
            for (int i = 0; i < n; ++i) d[i] += e * r[b][i];
            const std::vector<double> Td = applyT(d), Tu = applyT(u);
            for (int i = 0; i < n; ++i) {
                r[b][i] += Td[i];
                t[b][i] = e * t[b][i] + Tu[i];
            }
        }
        // R' = R + T R (I + S) T. D' = T (I + S) T - E E = E D + D E + D D + T S T.
        Matrix RM = matMul(R, S, n);
        for (size_t k = 0; k < RM.size(); ++k) RM[k] += R[k];
        const Matrix addR = rightT(leftT(RM));
        const Matrix TST = rightT(leftT(S));
        Matrix next = matMul(D, D, n);
        for (int i = 0; i < n; ++i) {
            for (int j = 0; j < n; ++j) {
                const size_t k = size_t(i) * n + j;
                next[k] += (E[i] + E[j]) * D[k] + TST[k];
                R[k] += addR[k];
            }
        }
        D.swap(next);
        h *= 2.0;
    }
    for (size_t b = 0; b < beams; ++b) {
        double up = 0, down = 0;
        for (int i = 0; i < n; ++i) {
            up += w[i] * mu[i] * r[b][i];
            down += w[i] * mu[i] * t[b][i];
        }
        SlabResult& o = out[b];
        o.reflectance = 2.0 * kPi * up / mu0s[b];
        o.transmittance = 2.0 * kPi * down / mu0s[b] + o.directTransmittance;
        o.absorptance = 1.0 - o.reflectance - o.transmittance;
        o.groundAbsorptance = o.transmittance;  // the black surface
    }
    return out;
}

} // namespace detail

/// @brief Adding-doubling solution for a homogeneous slab over a black surface, lit by a beam at
/// cosine @a mu0: the plane albedo and total transmittance of the exact transfer equation, up to
/// the angular quadrature (@a nodes Gauss points per hemisphere) and the start layer.
/// @details Azimuthally averaged intensities suffice for fluxes. Diffuse operators act on intensity
/// vectors at the nodes mu_i (weights w_i); the beam is carried separately as vectors r, t of
/// reflected and transmitted diffuse intensity per unit beam irradiance, so mu0 need not be a node.
/// Start layer dtau = tau / 2^N <= 1e-12, single scattering (van de Hulst 1980, ch. 4; Prahl 1988,
/// eqs. 3.30-3.32), with P(., .) the azimuthal mean of the phase function:
///     Rop_ij = omega0 P(mu_i, -mu_j) w_j / (2 mu_i) * (1 - exp(-dtau x+)) / x+,
///                                                                         x+ = 1/mu_i + 1/mu_j
///     Top_ij = delta_ij e^(-dtau/mu_i)
///              + omega0 P(mu_i, mu_j) w_j / (2 mu_i) * e^(-dtau/mu_i) expm1(dtau x-) / x-,
///                                                                         x- = 1/mu_i - 1/mu_j
///     r_i = omega0 P(mu_i, -mu0) / (4 pi mu_i) * (1 - exp(-dtau y+)) / y+,   y+ = 1/mu_i + 1/mu0
///     t_i = omega0 P(mu_i, mu0) / (4 pi mu_i) * e^(-dtau/mu_i) expm1(dtau y-) / y-,
///                                                                         y- = 1/mu_i - 1/mu0
/// Doubling two identical layers (u, d: down- and upwelling intensity between them, e the beam's
/// direct transmission): u = (I - R R)^-1 (t + e R r), d = e r + R u, then
///     r' = r + T d,  t' = e t + T u,  e' = e^2,
///     R' = R + T R (I - R R)^-1 T,  T' = T (I - R R)^-1 T.
/// Albedo = 2 pi sum_i w_i mu_i r_i / mu0; transmittance = 2 pi sum_i w_i mu_i t_i / mu0 + e.
/// Errors: the start layer's missing multiple scattering, ~dtau tau^2 (3e-10 at tau = 50); the
/// quadrature, which for g = 0.848 is ~1e-3 at 16 nodes, ~1e-5 at 32 and < 1e-9 at 64 (R + T = 1
/// for omega0 = 1 tracks it). Sharper peaks are beyond any affordable node count: at g = +-0.99
/// (tau 2, omega0 0.9) 64 nodes give T = 0.792 / 0.386 and 128 nodes 0.784 / 0.273 against the
/// photon Monte Carlo's 0.813 / 0.272, so |g| > 0.95 is refused: use slabMonteCarlo there. The
/// standard errors are zero; directTransmittance = exp(-tau/mu0); groundAbsorptance = T (the
/// black surface). Cost O(nodes^3 log2(tau/1e-12)): 0.05 s at 64 nodes. A tabulated phase
/// (p.legendre, chi_0..chi_L) is summed as its series, which the double-Gauss rule integrates
/// exactly from (L + 1) / 2 nodes on: cloud C.1 (L = 299) conserves energy to 1e-9 at 128 nodes
/// (0.9 s), and fewer than L / 2 give nonsense (64: R + T = 1.14 at tau 100).
/// @throw std::invalid_argument for parameters outside their ranges, |g| > 0.95 or nodes < 1.
inline SlabResult
addingDoublingSlab(const SlabProblem& p, int nodes = 64)
{
    return detail::addingDoublingBeams(p, {p.mu0}, nodes)[0];
}

/// @brief Homogeneous slab (p.tau, p.omega0, p.g) over a Lambertian ground of albedo
/// rho = p.groundAlbedo, lit by a beam at cosine p.mu0, by adding the ground to the slab:
///     R = R_s(mu0) + T_s(mu0) rho Tbar / (1 - rho Rbar),   E = T_s(mu0) / (1 - rho Rbar),
/// with R_s, T_s the black-ground plane albedo and total transmittance (addingDoublingSlab, at
/// @a nodes) and Rbar, Tbar their spherical values, 2 int_0^1 X(mu) mu dmu, the response to the
/// isotropic light the ground sends up (the homogeneous slab is symmetric, so light from below
/// sees the same R_s and T_s). The geometric series counts every return to the ground, so E is
/// the ground irradiance per unit entering beam, reported as transmittance; groundAbsorptance =
/// (1 - rho) E, absorptance = 1 - R - groundAbsorptance, directTransmittance = exp(-tau/mu0).
/// @details Rbar and Tbar by @a muNodes Gauss-Legendre points in mu on (0, 1). T_s carries the
/// beam exp(-tau/mu), smooth but steep near mu = 0; 24 and 48 points agree to 9e-10 at most
/// for tau in [0.5, 20], g 0 and 0.85 (12 points: 1.2e-7). All beams share one doubling, so the
/// cost is about that of one addingDoublingSlab. The standard errors are zero.
/// @throw std::invalid_argument as addingDoublingSlab, or for groundAlbedo outside [0,1] or
/// muNodes < 1.
inline SlabResult
slabOverGround(const SlabProblem& p, int nodes = 64, int muNodes = 24)
{
    detail::checkGroundAlbedo(p.groundAlbedo);
    if (muNodes < 1) throw std::invalid_argument("slabOverGround needs muNodes >= 1");
    std::vector<double> mu, w;
    detail::gaussLegendre01(muNodes, mu, w);
    std::vector<double> beams = mu;
    beams.push_back(p.mu0);
    const std::vector<SlabResult> s = detail::addingDoublingBeams(p, beams, nodes);
    const double rho = p.groundAlbedo;
    const SlabResult& beam = s.back();
    SlabResult out;
    out.directTransmittance = beam.directTransmittance;
    if (p.tau == 0.0) {
        // No slab: the ground alone (the quadrature would give Tbar = 1 only to rounding).
        out.reflectance = rho;
        out.transmittance = 1.0;
    } else {
        double rBar = 0, tBar = 0;
        for (int i = 0; i < muNodes; ++i) {
            rBar += 2.0 * w[i] * mu[i] * s[i].reflectance;
            tBar += 2.0 * w[i] * mu[i] * s[i].transmittance;
        }
        const double returns = 1.0 / (1.0 - rho * rBar);  // the ground-slab interreflections
        out.reflectance = beam.reflectance + beam.transmittance * rho * tBar * returns;
        out.transmittance = beam.transmittance * returns;
    }
    out.groundAbsorptance = (1.0 - rho) * out.transmittance;
    out.absorptance = 1.0 - out.reflectance - out.groundAbsorptance;
    return out;
}

// ---- Chandrasekhar's H-function ------------------------------------------------------------

/// @brief Chandrasekhar's H-function for isotropic scattering with albedo @a omega0 in [0, 1], at
/// @a mu in [0, 1], from its closed-form integral representation (Chandrasekhar 1960, Radiative
/// Transfer, ch. V; the form evaluated by Kawabata & Limaye 2011, arXiv:1010.4839):
///     H(mu) = exp[-(mu/pi) int_0^(pi/2) ln(1 - omega0 th cot th) / (cos^2 th + mu^2 sin^2 th) dth]
/// No iteration, so the conservative case (where fixed-point iterations of the H-equation crawl)
/// costs the same. Gauss-Legendre on th = (pi/2) s^2, which smooths the logarithmic singularity
/// at th = 0 when omega0 = 1; about 1e-7 relative for mu >= 0.1 with the default @a nodes (the
/// integrand peaks within ~mu of pi/2 as mu -> 0). The plane albedo of a semi-infinite isotropic
/// medium lit at mu0 is 1 - H(mu0) sqrt(1 - omega0) (Chandrasekhar 1960, ch. V).
inline double
chandrasekharH(double omega0, double mu, int nodes = 100)
{
    std::vector<double> s, w;
    detail::gaussLegendre01(nodes, s, w);
    double sum = 0;
    for (int i = 0; i < nodes; ++i) {
        const double th = 0.5 * kPi * s[i] * s[i], jacobian = kPi * s[i];
        const double c = std::cos(th), sn = std::sin(th);
        // 1 - th cot th by its series where the difference would cancel.
        const double t2 = th * th;
        const double oneMinusThCot = th < 1e-2
            ? t2 / 3.0 + t2 * t2 / 45.0 + 2.0 * t2 * t2 * t2 / 945.0 : 1.0 - th * c / sn;
        const double arg = (1.0 - omega0) + omega0 * oneMinusThCot;
        sum += w[i] * jacobian * std::log(arg) / (c * c + mu * mu * sn * sn);
    }
    return std::exp(-mu / kPi * sum);
}

} // namespace test
} // namespace vdbrad
