#include "vdbrad/cloud/ScatteredSource.h"

#include "vdbrad/core/Errors.h"
#include "vdbrad/core/GridContract.h"

#include <cmath>

namespace vdbrad {

namespace {
// The metadata keys on the mean-intensity grid.
constexpr const char* kScattering = "vdbrad:scattering";     // the source order K
constexpr const char* kPhase = "vdbrad:phase";               // PhaseFunction::text()
constexpr const char* kDeltaM = "vdbrad:delta_m";
constexpr const char* kToSun = "vdbrad:to_sun";              // index space, unit
constexpr const char* kSunIrradiance = "vdbrad:sun_irradiance";
constexpr const char* kPeriodic = "vdbrad:periodic";
constexpr const char* kUp = "vdbrad:up";

template<typename T>
T
required(const openvdb::GridBase& J, const char* key)
{
    const auto m = J.getMetadata<openvdb::TypedMetadata<T>>(key);
    if (!m) {
        OPENVDB_THROW(openvdb::ValueError, "grid '" << J.getName() << "' has " << kScattering
            << " but no " << key << " (not as a cloud solve wrote it)");
    }
    return m->value();
}
} // namespace

void
ScatteredSource::record(openvdb::GridBase& J) const
{
    J.insertMeta(kScattering, openvdb::Int32Metadata(order));
    J.insertMeta(kPhase, openvdb::StringMetadata(phase.text()));
    J.insertMeta(kDeltaM, openvdb::DoubleMetadata(deltaM));
    J.insertMeta(kToSun, openvdb::Vec3DMetadata(toSun));
    J.insertMeta(kSunIrradiance, openvdb::Vec3DMetadata(sunIrradiance));
    J.insertMeta(kPeriodic, openvdb::BoolMetadata(periodic));
    J.insertMeta(kUp, openvdb::Int32Metadata(up));
}

std::optional<ScatteredSource>
ScatteredSource::read(const openvdb::GridBase& J, const openvdb::GridPtrVec& grids)
{
    if (!J.getMetadata<openvdb::Int32Metadata>(kScattering)) return std::nullopt;
    ScatteredSource s;
    s.order = required<int32_t>(J, kScattering);
    s.deltaM = required<double>(J, kDeltaM);
    s.toSun = required<openvdb::Vec3d>(J, kToSun);
    s.sunIrradiance = required<openvdb::Vec3d>(J, kSunIrradiance);
    s.periodic = required<bool>(J, kPeriodic);
    s.up = required<int32_t>(J, kUp);
    try {
        s.phase = PhaseFunction::parse(required<std::string>(J, kPhase));
    } catch (const openvdb::ValueError& e) {
        OPENVDB_THROW(openvdb::ValueError, "grid '" << J.getName() << "': " << errorMessage(e));
    }
    bool finite = std::isfinite(s.deltaM);
    for (int k = 0; k < 3; ++k) {
        finite = finite && std::isfinite(s.toSun[k]) && std::isfinite(s.sunIrradiance[k])
            && s.sunIrradiance[k] >= 0.0;
    }
    if (s.order < 0 || s.order > kMaxOrder || !finite || !(s.deltaM >= 0.0 && s.deltaM < 1.0)
        || std::abs(s.toSun.length() - 1.0) > 1e-6 || s.up < 0 || s.up > 2) {
        OPENVDB_THROW(openvdb::ValueError, "grid '" << J.getName() << "': its scattering "
            "metadata is out of range (order " << s.order << ", delta-M " << s.deltaM
            << ", sun " << s.toSun << ", irradiance " << s.sunIrradiance << ")");
    }
    const int count = (s.order + 1) * (s.order + 1);
    for (int k = 0; k < count; ++k) {
        const std::string name = gridName(J.getName(), k);
        const openvdb::GridBase::ConstPtr g = findGrid(grids, name);
        if (!g) {
            OPENVDB_THROW(openvdb::ValueError, "grid '" << J.getName() << "' was solved with "
                "its scattered light's moments to order " << s.order << ", and grid '" << name
                << "' is missing");
        }
        if (g->type() != J.type() || g->transform() != J.transform()) {
            OPENVDB_THROW(openvdb::ValueError, "grid '" << name << "' is not of the type and "
                "on the transform of '" << J.getName() << "'");
        }
        s.moments.push_back(g);
    }
    return s;
}

} // namespace vdbrad
