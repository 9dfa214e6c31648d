// SphericalHarmonics: functions on the sphere of directions as truncated real spherical-harmonic
// expansions, with the same operations as ControlPoints (query, projection, fit, rotation), so
// that the two representations of glossy BRDFs and radiance (thesis §5.2) can be compared on
// equal terms: fit error against coefficient count, time per operation.
//
// An expansion of order L keeps (L + 1)^2 coefficients c_lm, l = 0..L, m = -l..l, at index
// l^2 + l + m, of realSphericalHarmonics' orthonormal Y_lm (no Condon-Shortley phase), so
//     f(w) = sum_lm c_lm Y_lm(w),   c_lm = int f Y_lm dOmega.
//
// Rotation: g(w) = f(R^T w) has, band by band, c'_l = D^l(R) c_l with a (2l + 1)^2 block D^l
// built by Ivanic and Ruedenberg's recurrences (J. Phys. Chem. 100:6342, 1996; erratum
// 102:9099, 1998): D^1 is R itself, rows and columns reordered (y, z, x) as Y_1,-1..Y_11 are
// proportional to y, z, x, and D^l follows from D^{l-1} and D^1 in O(1) per entry. Their real
// harmonics carry no Condon-Shortley phase, exactly realSphericalHarmonics' convention, so no
// sign changes are needed (tests/test_spherical_harmonics.cc checks g against f(R^T w) at
// orders 0-10 to 1e-10). Building D costs O(L^3) and so does applying it, against O(L^4) or
// worse for resampling and refitting.
//
// Zonal functions h(w . a) (lobes around an axis a, such as a Phong cosine power) have, by the
// addition theorem, c_lm = sqrt(4 pi / (2l + 1)) z_l Y_lm(a) with z_l = int h(w . z) Y_l0 dOmega,
// so a lobe is set up around any axis without a rotation matrix.
#pragma once

#include <openvdb/math/Mat3.h>
#include <openvdb/math/Vec3.h>

#include <cstddef>
#include <functional>
#include <vector>

namespace vdbrad {

class SphericalHarmonics
{
public:
    /// Highest order: 1089 coefficients, beyond which rotation blocks and fits grow impractical.
    static constexpr int kMaxOrder = 32;

    /// @brief Expansions of order @a order ((order + 1)^2 coefficients).
    /// @throw openvdb::ValueError if @a order is outside [0, kMaxOrder]
    explicit SphericalHarmonics(int order);

    int order() const { return mOrder; }
    /// (order + 1)^2.
    size_t size() const { return size_t(mOrder + 1) * size_t(mOrder + 1); }

    /// Y_lm(@a dir), size() values (realSphericalHarmonics); @a dir need not be unit.
    void basis(const openvdb::math::Vec3d& dir, double* out) const;
    /// The expansion @a coeffs (size() of them) at @a dir: the query. Allocates nothing.
    double evaluate(const double* coeffs, const openvdb::math::Vec3d& dir) const;

    /// @brief Projection by quadrature: c_lm = sum_k weights_k values_k Y_lm(dirs_k). Exact
    /// for band-limited f when the weights integrate harmonics of order 2L exactly (e.g.
    /// ControlPoints::areas() or HarmonicQuadrature for cruder sets).
    /// @throw openvdb::ValueError if the three vectors differ in size
    std::vector<double> project(const std::vector<openvdb::math::Vec3d>& dirs,
        const std::vector<double>& weights, const std::vector<double>& values) const;

    /// @brief Least-squares fit to samples: minimise
    ///     sum_k (sum_lm c_lm Y_lm(dirs_k) - values_k)^2 + lambda sum_lm c_lm^2.
    /// Solved by column-pivoting Householder QR of the samples' basis matrix (stacked over
    /// sqrt(lambda) I for lambda > 0), not by the normal equations: those square the condition
    /// number, and samples on one hemisphere only (a BRDF) make it large at high orders.
    /// @throw openvdb::ValueError if the sizes differ, @a lambda is negative or not finite,
    /// or, for lambda = 0, the samples do not determine all coefficients (fewer samples than
    /// coefficients, or numerically dependent columns)
    std::vector<double> fit(const std::vector<openvdb::math::Vec3d>& dirs,
        const std::vector<double>& values, double lambda = 0.0) const;

    /// @a coeffs *= @a s (n values); here, beside ControlPoints' equivalents, for benchmarks.
    static void scale(double s, double* coeffs, size_t n);
    /// @a b += @a a (n values).
    static void add(const double* a, double* b, size_t n);

    /// The block-diagonal matrix rotating expansions up to some order (see the file comment).
    class Rotation
    {
    public:
        int order() const { return mOrder; }
        /// Band @a l's (2l + 1)^2 block, row-major, rows and columns m = -l..l:
        /// c'_lm = sum_n block(l)[(m + l)(2l + 1) + n + l] c_ln.
        const double* block(int l) const { return mBlocks.data() + blockOffset(l); }
        /// @brief out = D in over bands 0..order(); @a in and @a out may not alias.
        void apply(const double* in, double* out) const;
        /// Start of band @a l's block: sum_{k < l} (2k + 1)^2.
        static size_t blockOffset(int l) { return size_t(l) * (2 * l - 1) * (2 * l + 1) / 3; }

    private:
        friend class SphericalHarmonics;
        int mOrder = 0;
        std::vector<double> mBlocks{1.0};   // default: the order-0 identity
    };

    /// @brief The rotation taking f's coefficients to those of g(w) = f(R^T w), for a proper
    /// rotation @a R applied to column vectors (w' = R w, as ControlPoints::rotation). Note
    /// that openvdb::math::rotation<Mat3d>() returns matrices for row vectors (v * M): pass
    /// their transpose.
    /// @throw openvdb::ValueError if @a R is not orthonormal with det +1 (to 1e-6)
    Rotation rotation(const openvdb::math::Mat3d& R) const;
    /// @brief @a out = @a r applied to @a in (size() values each; may not alias).
    /// @throw openvdb::ValueError if @a r has a lower order than this
    void rotate(const Rotation& r, const double* in, double* out) const;

    /// @brief The coefficients of h(w . @a axis) = sum_l z_l Y_l0 evaluated at cos = w . axis,
    /// given its zonal coefficients @a z (z_l for l > order() are dropped: truncation is the
    /// least-squares projection; missing ones are 0).
    /// @throw openvdb::ValueError if @a axis is zero or not finite
    std::vector<double> zonal(const std::vector<double>& z, const openvdb::math::Vec3d& axis) const;

    /// @brief Zonal coefficients z_l = 2 pi int_{-1}^{1} h(mu) Y_l0(mu) dmu, l = 0..@a order,
    /// by Gauss-Legendre quadrature with @a points nodes on each of [-1, 0] and [0, 1]
    /// (default 2 (order + 1) + 16). Splitting at mu = 0 makes clamped lobes such as
    /// max(0, mu)^n, which are polynomials on either side, exact up to n + order <= 2 points - 1.
    /// @throw openvdb::ValueError if @a order is outside [0, kMaxOrder] or @a points < 0
    static std::vector<double> zonalCoefficients(int order, const std::function<double(double)>& h,
        int points = 0);

private:
    int mOrder;
    // The recurrences' coefficients u, v, w per (l, m, n), l >= 2, at Rotation::blockOffset(l)
    // + (m + l)(2l + 1) + n + l; v carries the sqrt(2) of the |m| = 1 rows.
    std::vector<double> mU, mV, mW;
};

/// @brief Gauss-Legendre nodes and weights on [-1, 1] (@a n >= 1 points, exact for polynomials
/// of degree 2n - 1).
void gaussLegendre(int n, std::vector<double>& nodes, std::vector<double>& weights);

} // namespace vdbrad
