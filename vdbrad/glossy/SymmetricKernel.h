// SymmetricKernel: a dense symmetric matrix kept in float and in double and applied to columns
// of values with Eigen (private to the library: no header includes it). The glossy lobes'
// kernels on control points (ControlBrdf.h) and on harmonics (HarmonicBrdf.h) are such
// matrices: the solver reflects in its state's precision, float products being half the
// memory traffic.
#pragma once

#include <cstddef>
#include <vector>

namespace vdbrad {

class SymmetricKernel
{
public:
    /// @brief Take the @a n x @a n symmetric @a values (row-major, hence column-major too);
    /// the float copy rounds them.
    void assign(size_t n, std::vector<double> values);

    size_t size() const { return mSize; }
    const std::vector<double>& wide() const { return mWide; }
    const std::vector<float>& narrow() const { return mNarrow; }

    /// @brief out = K in: @a in and @a out hold @a width columns of size() values. S: float
    /// (the float copy) or double.
    template<typename S> void apply(const S* in, S* out, int width) const;

private:
    size_t mSize = 0;
    std::vector<float> mNarrow;
    std::vector<double> mWide;
};

} // namespace vdbrad
