// CloudRequest: `vdbrad solve-cloud` and vdbrad.solve_cloud() described once: every option of a
// fog volume's solve (cloudSolveOptions()), read into CloudOptions and CloudTransferOptions
// and checked together; the plan; the solve, with the surfaces of a scene among the same grids;
// its result.
#pragma once

#include "vdbrad/request/SolvePlan.h"

#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/scene/Cloud.h"
#include "vdbrad/scene/Scene.h"

#include <openvdb/util/NullInterrupter.h>
#include <memory>

#include <string>
#include <vector>

namespace vdbrad {

/// Every option of a cloud solve.
const std::vector<OptionSpec>& cloudSolveOptions();

/// A cloud solve in the steps a host may come between: read, plan, run.
class CloudSolve
{
public:
    /// @brief Read @a request (of cloudSolveOptions()); @a request must outlive this.
    /// @throw OptionError for options that contradict each other
    CloudSolve(const Request& request, const Distribution* ranks = nullptr);

    const CloudOptions& cloudOptions() const { return mCloudOptions; }

    /// @brief Build the medium (and the surfaces, if the grids hold a scene and the request
    /// does not leave them out) from @a grids.
    /// @throw openvdb::Exception as buildCloud() and buildScene(), or for surfaces these
    ///        options cannot solve
    void read(const openvdb::GridPtrVec& grids, openvdb::util::NullInterrupter* interrupt);
    /// @brief Directions, memory and time. @throw MemoryLimitError past the memory limit
    const SolvePlan& plan();
    /// @brief Solve (plan() first if not done): the mean radiance grid (named by
    /// --output-name, with the emission's metadata), and where present the ground's
    /// irradiance and the surfaces' radiosity.
    SolveResult run(openvdb::util::NullInterrupter* interrupt, SolveControl control);

    const std::vector<std::string>& warnings() const { return mWarnings; }

private:
    const Request& mRequest;
    const Distribution* mRanks;
    CloudOptions mCloudOptions;
    CloudTransferOptions mOptions;
    Scene mScene;
    Cloud mCloud;
    std::unique_ptr<Cloud> mSlice;   // what a periodic box uniform along an axis solves (plan())
    double mInputBytes = 0.0;
    bool mRead = false, mPlanned = false;
    SolvePlan mPlan;
    std::vector<std::string> mWarnings;
};

/// @brief One call: read(), plan() and run() of @a request on @a grids.
SolveResult solveClouds(const openvdb::GridPtrVec& grids, const Request& request,
    const Distribution* ranks = nullptr, openvdb::util::NullInterrupter* interrupt = nullptr,
    SolveControl control = SolveControl());

} // namespace vdbrad
