// PhaseFunction: how a medium voxel redistributes the light it scatters, as the Legendre
// coefficients the source iteration needs, with delta-M scaling (Wiscombe 1977).
//
// A phase function normalised to (1/4pi) int p dOmega = 1 expands as
//     p(cos Theta) = sum_l (2l + 1) chi_l P_l(cos Theta),   chi_0 = 1,
// (Henyey-Greenstein: chi_l = g^l). The sweeps keep, per voxel, the moments of the radiance
// I_lm = int L Y_lm dOmega up to order K (real orthonormal spherical harmonics, (K+1)^2 numbers;
// none beyond J for isotropic scattering), and by the addition theorem the scattered source is
//     S(s) = omega0 sum_{l <= K} chi_l sum_m I_lm Y_lm(s).
// A forward peak needs many orders; delta-M moves the fraction f = chi_{K+1} of the scattering
// into the unscattered direction instead (sigma_t' = (1 - omega0 f) sigma_t,
// omega0' = (1 - f) omega0 / (1 - omega0 f), chi_l' = (chi_l - f) / (1 - f)), which keeps fluxes
// accurate with a small K.
#pragma once

#include "vdbrad/sweep/DirectionSet.h"

#include <openvdb/Types.h>

#include <string>
#include <vector>

namespace vdbrad {

class PhaseFunction
{
public:
    /// Isotropic scattering (chi_l = 0 for l > 0).
    PhaseFunction() : mChi{1.0} {}

    /// @brief Henyey-Greenstein with asymmetry @a g in (-1, 1).
    /// @throw openvdb::ValueError otherwise
    static PhaseFunction henyeyGreenstein(double g);

    /// @brief A phase given by its Legendre coefficients chi_0 = 1, chi_1, ... (e.g. Mie); later
    /// coefficients are taken as 0.
    /// @throw openvdb::ValueError if chi_0 != 1 or some |chi_l| > 1
    static PhaseFunction legendre(std::vector<double> chi);

    /// @brief legendre() of the coefficients chi_0 = 1, chi_1, ... in the text file @a path
    /// (a Mie code's output; samples/phase/): numbers separated by white space or commas, `#`
    /// starting a comment.
    /// @throw openvdb::IoError if the file cannot be read; openvdb::ValueError for a word that
    /// is not a number (naming its line), no coefficients, more than kMaxCoefficients, or as
    /// legendre(), with a hint where the numbers are (2l + 1) chi_l (tables such as Garcia and
    /// Siewert's list those)
    static PhaseFunction readLegendre(const std::string& path);
    static constexpr size_t kMaxCoefficients = 100000;

    /// chi_l (0 beyond the known coefficients, or g^l for Henyey-Greenstein).
    double chi(int l) const;
    /// @brief p(mu), normalised to (1/4pi) int p dOmega = 1: Henyey-Greenstein's closed form,
    /// or the Legendre series of the given coefficients.
    double value(double mu) const;
    /// The asymmetry parameter g = chi_1.
    double asymmetry() const { return chi(1); }
    bool isIsotropic() const { return !mHg && mChi.size() == 1; }

    /// @brief The phase function as one line of text that parse() reads back to the same
    /// function, bit for bit: "isotropic", "hg G" or "legendre chi_0 chi_1 ..." (a solved
    /// cloud's file carries it for the renderer's single scattering).
    std::string text() const;
    /// @throw openvdb::ValueError if @a text is not what text() writes
    static PhaseFunction parse(const std::string& text);

    /// The delta-M truncation at order K: the fraction f = chi_{K+1} moved forward, and the
    /// scaled coefficients chi_l', l = 0..K. K = 0 gives isotropic scattering with the
    /// transport correction f = g (the classical similarity scaling).
    struct Truncated
    {
        double f = 0.0;
        std::vector<double> chi;
    };
    Truncated truncate(int order) const;

    /// The phase function on the directions of a sweep (CloudTransfer), at order K.
    struct Tables
    {
        /// (K + 1)^2 values per direction and sense (index 2 d + sense, sense 1: -sigma): the
        /// real spherical harmonics Y_lm of the direction of travel, with which moments are
        /// accumulated and sources evaluated.
        std::vector<float> harmonics;
        /// Mean of each Y_lm over the direction set (its solid-angle weights integrate high
        /// orders only roughly: Y_00 exactly, order 8 a few per cent off).
        std::vector<double> quadratureMean;
        /// First scattering of a beam, per direction and sense: the full phase function (not
        /// its truncation) divided by 1 - f, less the forward fraction f delta-M keeps in the
        /// beam, taken from the directions closest to the beam's, so that
        /// sum_s Omega_s T_s = 4 pi exactly (DISORT's TMS idea, applied to the source).
        std::vector<float> beam;
    };
    /// @brief Tables() over @a directions at order @a order, for a beam travelling along
    /// @a beam (unit, index space).
    Tables tables(const DirectionSet& directions, int order, const openvdb::Vec3d& beam) const;

private:
    std::vector<double> mChi;
    bool mHg = false;
    double mG = 0.0;
};

} // namespace vdbrad
