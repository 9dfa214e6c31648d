// Commands: the table of the tool's commands, and the entry point that runs one.
#pragma once

#include "CommandLine.h"

#include <vector>

namespace vdbrad {

class Distribution;

namespace cli {

/// Every command, in the order help lists them.
const std::vector<CommandSpec>& commands();

/// @brief Run the tool on @a args (argv without the program name); returns the exit status:
/// 0 success, 1 bad input or failure, 2 bad command line, 130 cancelled by a signal.
/// Only this function maps errors to exit statuses and prints them (one line on stderr).
/// @a ranks: the MPI job the solves are shared with (Distribution::join()); null: this process.
int runTool(const std::vector<std::string>& args, const Distribution* ranks = nullptr);

// The code behind each command of the table, one file each (Command<Name>.cc). They run on
// arguments the table has already checked, and return the exit status.
int runMake(const Arguments& a);
int runVoxelize(const Arguments& a);
int runInfo(const Arguments& a);
int runSurface(const Arguments& a);
int runCompare(const Arguments& a);
int runSolve(const Arguments& a);
int runSolveCloud(const Arguments& a);
int runRender(const Arguments& a);

} // namespace cli
} // namespace vdbrad
