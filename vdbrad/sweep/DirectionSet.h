// DirectionSet: the integer sweep directions of the line-partition radiosity method and their
// direction factors (Chatelier & Malgouyres, thesis 2006, §4.1.2.2 and §4.3.4).
//
// The solver partitions space into discrete lines along integer directions σ = (a, b, c) and
// exchanges light along each line. A sweep along σ serves σ and −σ at once, so the set keeps one
// direction per ± pair. The directions are read off a discrete sphere:
//
//   * B_R = { p ∈ Z³ : |p|² ≤ R² }, the digital ball of integer radius R ≥ 1 (closed: a voxel
//     whose centre lies exactly on the sphere belongs to the ball);
//   * its boundary surfels are the unit squares between a voxel p ∈ B_R and a face neighbour
//     q ∉ B_R: the face of the unit cube centred at p that faces q;
//   * each surfel, seen from the origin, subtends an exact solid angle (two triangles,
//     Van Oosterom–Strackee); it is credited to the primitive direction p / gcd(|p_x|,|p_y|,|p_z|).
//
// Facts this relies on (proved in DirectionSet.cc, checked by tests/test_directions.cc):
//   * every boundary surfel faces away from the origin, so its signed solid angle is > 0 and the
//     surfels tile the unit sphere of directions exactly once: the angles sum to 4π;
//   * a ray from the origin meets at most one voxel with an exposed face, so each primitive
//     direction owns the surfels of a single voxel;
//   * the exposed voxels of B_R are exactly the p with |p|² ≤ R² < |p|² + 2‖p‖∞ + 1, one per
//     (axis, two other coordinates): the set is built from the boundary shell in O(R²).
//
// Normalisation. With Ω(σ) the solid angle (steradians) credited to σ (Ω(σ) = Ω(−σ) by the point
// symmetry of B_R) the factor of the pair is
//
//     A(σ) = (Ω(σ) + Ω(−σ)) / (2π) = Ω(σ) / π,     Σ_pairs A(σ) = 4π / (2π) = 2 exactly,
//
// so that for a receiver of unit normal n, Σ_pairs |σ̂·n| A(σ) ≈ (1/π) ∫_hemisphere cos θ dω = 1.
// The sum is only ≈ 1 (each pair's cosine is taken at σ̂, not averaged over its solid angle;
// max |sum − 1| over normals is about 0.037 / R, e.g. 0.0049 at R = 8); the
// solver must therefore use the per-receiver normalised weights
//
//     w_σ(n) = |σ̂·n| A(σ) / hemisphereSum(n),     Σ_pairs w_σ(n) = 1 for every n,
//
// which conserve energy exactly. hemisphereSum(n) can be accumulated per voxel during the first
// sweep, at no extra pass.
#pragma once

#include <openvdb/Exceptions.h>
#include <openvdb/math/Coord.h>
#include <openvdb/math/Vec3.h>

#include <cstdint>
#include <vector>

namespace vdbrad {

class DirectionSet
{
public:
    /// Largest radius accepted by fromRadius(); fromCount() accepts counts up to
    /// countForRadius(kMaxRadius) = maxCount() = 834,159 pairs.
    static constexpr int kMaxRadius = 400;

    /// An empty set (radius 0, no directions).
    DirectionSet() = default;

    /// @brief The directions of the boundary of B_R, one per ± pair.
    /// @param radius  R, in voxels, in [1, kMaxRadius]. Build time and memory are O(R²)
    ///                (48 bytes per pair; R = 100: 51,867 pairs, 2.5 MB; R = 400: 834,159
    ///                pairs, 40 MB; build times: docs/journal/2026-12-03-direction-set.md).
    /// @throw openvdb::ValueError if @a radius is outside [1, kMaxRadius].
    static DirectionSet fromRadius(int radius);

    /// @brief The set whose pair count is nearest @a count (ties: the smaller radius; the count
    ///        strictly increases with R so that is also the smaller count). The achieved count
    ///        is size().
    /// @throw openvdb::ValueError if @a count < 1 or @a count > maxCount().
    static DirectionSet fromCount(int count);

    /// @brief Number of pairs fromRadius(@a radius) has, without computing solid angles
    ///        (O(R²) integer work).
    /// @throw openvdb::ValueError if @a radius is outside [1, kMaxRadius].
    static size_t countForRadius(int radius);

    /// countForRadius(kMaxRadius): the largest count fromCount() accepts.
    static size_t maxCount();

    /// Number of direction pairs.
    size_t size() const { return mDirections.size(); }
    bool empty() const { return mDirections.empty(); }

    /// R of the sphere the set was built from (0 for an empty set).
    int radius() const { return mRadius; }

    /// @brief Primitive integer direction of pair @a k: gcd of |components| is 1 and its first
    ///        non-zero component is positive (the pair's other member is −direction(k)).
    ///        Pairs are stored in increasing lexicographic order of direction(k).
    const openvdb::math::Coord& direction(size_t k) const { return mDirections[k]; }

    /// direction(k) normalised to unit length.
    const openvdb::math::Vec3d& unit(size_t k) const { return mUnits[k]; }

    /// @brief Direction factor A of pair @a k, dimensionless, > 0: the solid angle of the pair
    ///        (both orientations) over 2π, i.e. the solid angle of one orientation over π.
    double factor(size_t k) const { return mFactors[k]; }

    /// @brief Smallest radius r ≤ radius() at which direction(k) is already a direction of the
    ///        boundary of B_r (in [1, radius()]); the key of progressiveOrder().
    int appearanceRadius(size_t k) const { return mAppearance[k]; }

    /// @brief A permutation of 0..size()-1 with the directions of smaller spheres first
    ///        (thesis fig. 4.14): increasing appearanceRadius(), then increasing |σ|², then
    ///        increasing index. Starts with the three axis directions.
    std::vector<size_t> progressiveOrder() const;

    /// @brief A deterministic pseudo-random permutation of 0..size()-1 (splitmix64 and
    ///        Fisher–Yates with exact rejection sampling: the same on every platform).
    std::vector<size_t> shuffledOrder(uint64_t seed) const;

    /// @brief Raw sum Σ_pairs |σ̂·n| A(σ) for a unit normal @a n (≈ 1; the result scales with
    ///        |n|). Divide each weight by it to conserve energy (see the file comment).
    double hemisphereSum(const openvdb::math::Vec3d& n) const;
    /// @brief 1 / hemisphereSum(n) for each of @a normals (unit), in parallel: the solvers'
    /// per-voxel normalisation.
    std::vector<double> inverseHemisphereSums(
        const std::vector<openvdb::math::Vec3s>& normals) const;

    /// @brief The energy-conserving weights w_σ(n) = |σ̂·n| A(σ) / hemisphereSum(n), one per pair,
    ///        in index order; they add up to 1. @a n need not be normalised. Reference code: the
    ///        solver accumulates these itself.
    /// @throw openvdb::ValueError if @a n is zero (or not finite) or the set is empty.
    std::vector<double> normalisedWeights(const openvdb::math::Vec3d& n) const;

    /// @brief The cell a direction falls in: the pair whose surfels (see the file comment) the
    ///        ray from the origin along @a d crosses, as 2k for +direction(k) and 2k + 1 for
    ///        −direction(k). The cells tile the sphere, so a function of direction averaged over
    ///        each cell (Sky::cellMeans) is integrated exactly once. O(radius()) per call.
    /// @throw openvdb::ValueError if @a d is zero or not finite, or the set is empty
    size_t cellOf(const openvdb::math::Vec3d& d) const;

    /// @brief This set with other pair factors (e.g. HarmonicQuadrature's).
    /// @throw openvdb::ValueError unless there is one per pair, each > 0, adding up to 2 (1e-9)
    DirectionSet withFactors(std::vector<double> factors) const;

private:
    int mRadius = 0;
    std::vector<openvdb::math::Coord> mDirections;
    std::vector<openvdb::math::Vec3d> mUnits;
    std::vector<double> mFactors;
    std::vector<int> mAppearance;
};

} // namespace vdbrad
