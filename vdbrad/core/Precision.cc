#include "vdbrad/core/Precision.h"

#include <openvdb/Exceptions.h>

namespace vdbrad {

namespace {

// Largest albedo channel of any voxel.
float
maxAlbedo(const Attribute& a)
{
    float top = a.uniformValue();
    for (float v : a.greyArray()) top = std::max(top, v);
    for (const openvdb::Vec3f& v : a.rgbArray()) top = std::max({top, v[0], v[1], v[2]});
    return top;
}

} // namespace

bool
solvesInDouble(const Attribute& albedo, Precision precision)
{
    switch (precision) {
        case Precision::Float: return false;
        case Precision::Double: return true;
        case Precision::Auto: break;
    }
    return maxAlbedo(albedo) > kDoubleAlbedo;
}

Precision
precisionFromString(const std::string& name)
{
    if (name == "auto") return Precision::Auto;
    if (name == "float") return Precision::Float;
    if (name == "double") return Precision::Double;
    OPENVDB_THROW(openvdb::ValueError, "unknown precision '" << name
        << "' (expected auto, float or double)");
}

const char*
toString(Precision p)
{
    switch (p) {
        case Precision::Float: return "float";
        case Precision::Double: return "double";
        case Precision::Auto: break;
    }
    return "auto";
}

} // namespace vdbrad
