// SurfaceRequest: `vdbrad solve` and vdbrad.solve() described once: every option of a surface
// solve (declared in surfaceSolveOptions() with its default, range and help), read into the
// solvers' options and checked together; the plan; the solve; its result.
//
//     vdbrad::Request request("solve", vdbrad::surfaceSolveOptions());
//     request.set("directions", "1000");
//     vdbrad::SolveResult lit = vdbrad::solveSurfaces(grids, request);   // lit.grids: radiosity
#pragma once

#include "vdbrad/request/SolvePlan.h"

#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/surface/RadiositySolver.h"

#include <openvdb/util/NullInterrupter.h>

#include <optional>
#include <string>
#include <vector>

namespace vdbrad {

/// Every option of a surface solve.
const std::vector<OptionSpec>& surfaceSolveOptions();

/// A surface solve in the steps a host may come between: read, plan, run.
class SurfaceSolve
{
public:
    /// @brief Read @a request (of surfaceSolveOptions()) into the solvers' options.
    /// @throw OptionError for options that contradict each other
    SurfaceSolve(const Request& request, const Distribution* ranks = nullptr);

    const SceneOptions& sceneOptions() const { return mSceneOptions; }

    /// @brief Build the scene from @a grids and check what depends on it (glossy surfaces).
    /// @throw openvdb::Exception as buildScene(), or for a scene these options cannot solve
    void read(const openvdb::GridPtrVec& grids, openvdb::util::NullInterrupter* interrupt);
    /// @brief Directions, memory and time, and the visibility cache's size (auto: half of what
    /// the memory limit leaves). Call once the host holds no more than it will while solving.
    /// @throw MemoryLimitError past the memory limit
    const SolvePlan& plan();
    /// @brief Solve (plan() first if not done). @a control reports the iterations; its
    /// checkpoint files are the request's.
    SolveResult run(openvdb::util::NullInterrupter* interrupt, SolveControl control);

    /// Warnings so far (the scene's, then the solve's).
    const std::vector<std::string>& warnings() const { return mWarnings; }

private:
    const Request& mRequest;
    const Distribution* mRanks;
    SceneOptions mSceneOptions;
    RadiosityOptions mOptions;
    MonteCarloOptions mMonteCarlo;
    std::string mMethod;
    double mCache = -1.0;        // bytes, or -1 for auto
    double mInputBytes = 0.0;
    Scene mScene;
    bool mRead = false, mPlanned = false;
    SolvePlan mPlan;
    std::vector<std::string> mWarnings;
};

/// @brief One call: read(), plan() and run() of @a request on @a grids.
SolveResult solveSurfaces(const openvdb::GridPtrVec& grids, const Request& request,
    const Distribution* ranks = nullptr, openvdb::util::NullInterrupter* interrupt = nullptr,
    SolveControl control = SolveControl());

/// The light from outside a scene a solve used: its sky (empty: none) and its sun.
struct OutsideLight
{
    Sky sky;
    std::optional<Sun> sun;
};

/// @brief Record on @a grid the light from outside @a request (a surface or cloud solve's) was
/// given (--sky, --sky-model, --environment, --sun and theirs) as `vdbrad:light` metadata, one
/// `name=value` per line (nothing if none), for solvedLight().
void recordLight(const Request& request, openvdb::GridBase& grid);

/// @brief The light a solved file was lit by from outside: its radiosity grid's (else any
/// grid's, a cloud solve's)
/// `vdbrad:light` metadata (the solve's --sky, --sky-model, --environment, --sun and theirs,
/// one `name=value` per line), read as the solve read them. Nothing if the file has none. A
/// map that cannot be read any more gives a warning in @a warnings and no sky.
OutsideLight solvedLight(const openvdb::GridPtrVec& grids, std::vector<std::string>& warnings);

/// @brief The warning a host gives when @a result stopped at the iteration cap short of the
/// tolerance; empty if it converged.
std::string stoppedShort(const SolveResult& result, const Request& request);

} // namespace vdbrad
