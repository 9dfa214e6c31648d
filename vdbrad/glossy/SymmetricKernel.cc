#include "vdbrad/glossy/SymmetricKernel.h"

#include <Eigen/Core>

#include <type_traits>

namespace vdbrad {

void
SymmetricKernel::assign(size_t n, std::vector<double> values)
{
    mSize = n;
    mWide = std::move(values);
    mNarrow.assign(mWide.begin(), mWide.end());
}

template<typename S>
void
SymmetricKernel::apply(const S* in, S* out, int width) const
{
    using Matrix = Eigen::Matrix<S, Eigen::Dynamic, Eigen::Dynamic>;
    const Eigen::Index n = Eigen::Index(mSize);
    const S* k = nullptr;
    if constexpr (std::is_same_v<S, float>) k = mNarrow.data();
    else k = mWide.data();
    // Symmetric: its row-major storage is also its column-major one.
    const Eigen::Map<const Matrix> K(k, n, n);
    Eigen::Map<Matrix>(out, n, width).noalias() = K * Eigen::Map<const Matrix>(in, n, width);
}

template void SymmetricKernel::apply(const float*, float*, int) const;
template void SymmetricKernel::apply(const double*, double*, int) const;

} // namespace vdbrad
