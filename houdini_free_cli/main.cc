// vdbrad: the Houdini-free command-line host of the vdbrad library.
#include "Commands.h"

int
main(int argc, char** argv)
{
    return vdbrad::cli::runTool(std::vector<std::string>(argv + 1, argv + argc));
}
