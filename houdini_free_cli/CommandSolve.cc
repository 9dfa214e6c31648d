// `vdbrad solve`: the radiosity of a surface scene (vdbrad/request/SurfaceRequest.h: the line
// sweeps, or a reference: ray marching along the same lines, or Monte Carlo rays).
#include "Commands.h"
#include "Progress.h"
#include "SolveSupport.h"
#include "ToolSupport.h"

#include "vdbrad/core/GridContract.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/request/SurfaceRequest.h"

#include <utility>

namespace vdbrad {
namespace cli {

int
runSolve(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    SurfaceSolve solve(a.request(), &job());
    SolveSession session(a, in, out);
    const std::string& label = session.label();
    describeReading(a, label, session.file(), solve.sceneOptions().surface, names::kDensity);
    forFile(label, [&] { solve.read(session.file().grids, &session.progress()); });
    session.warn(solve.warnings());
    session.releaseInput();
    const SolvePlan& plan = forFile(label, [&]() -> const SolvePlan& { return solve.plan(); });
    // Not under forFile: a failure here (memory, a checkpoint) says itself, and under mpirun
    // stops the job (runTool()).
    const SolveResult result = solve.run(&session.progress(), session.control(plan.describe()));
    session.finish(result, out);
    return 0;
}

} // namespace cli
} // namespace vdbrad
