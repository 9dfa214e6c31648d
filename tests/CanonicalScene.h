// A canonical scene (grids/) built as a vdbrad::Scene, for the solver tests.
#pragma once

#include "grids/CanonicalGrids.h"
#include "vdbrad/scene/Scene.h"

#include <string>

namespace vdbrad {
namespace test {

/// Canonical scene @a name at resolution @a res; negative albedo or emission: the default.
inline Scene
canonicalScene(const std::string& name, int res, float albedo = -1.f, float emission = -1.f)
{
    grids::BuildParams p;
    p.res = res;
    p.albedo = albedo;
    p.emission = emission;
    return buildScene(grids::findBuilder(name)->build(p));
}

} // namespace test
} // namespace vdbrad
