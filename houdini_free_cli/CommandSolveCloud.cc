// `vdbrad solve-cloud`: the light in a fog volume lit by the sun, with the surfaces of a scene
// in the same file (vdbrad/request/CloudRequest.h).
#include "Commands.h"
#include "Progress.h"
#include "SolveSupport.h"
#include "ToolSupport.h"

#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/request/CloudRequest.h"

namespace vdbrad {
namespace cli {

int
runSolveCloud(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    CloudSolve solve(a.request(), &job());
    SolveSession session(a, in, out);
    const std::string& label = session.label();
    describeReading(a, label, session.file(), "", solve.cloudOptions().density);
    forFile(label, [&] { solve.read(session.file().grids, &session.progress()); });
    session.warn(solve.warnings());
    const SolvePlan& plan = forFile(label, [&]() -> const SolvePlan& { return solve.plan(); });
    const SolveResult result = forFile(label, [&] {
        return solve.run(&session.progress(), session.control(plan.describe()));
    });
    session.finish(result, out);
    return 0;
}

} // namespace cli
} // namespace vdbrad
