// Commands: the table of the tool's commands and the code behind each.
#pragma once

#include "CommandLine.h"

#include <vector>

namespace vdbrad {
namespace cli {

/// Every command, in the order help lists them.
const std::vector<CommandSpec>& commands();

/// @brief Run the tool on @a args (argv without the program name); returns the exit status:
/// 0 success, 1 bad input or failure, 2 bad command line, 130 cancelled by a signal.
/// Only this function maps errors to exit statuses and prints them (one line on stderr).
int runTool(const std::vector<std::string>& args);

} // namespace cli
} // namespace vdbrad
