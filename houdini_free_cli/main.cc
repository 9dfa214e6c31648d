// vdbrad: the Houdini-free command-line host of the vdbrad library.
#include "Commands.h"

#include "vdbrad/distribute/Distribution.h"

#include <memory>

int
main(int argc, char** argv)
{
    // Before any thread starts: under mpirun this initialises MPI (vdbrad/distribute/Distribution.h).
    const std::unique_ptr<vdbrad::Distribution> ranks = vdbrad::Distribution::join();
    const int status =
        vdbrad::cli::runTool(std::vector<std::string>(argv + 1, argv + argc), ranks.get());
    ranks->finalize();
    return status;
}
