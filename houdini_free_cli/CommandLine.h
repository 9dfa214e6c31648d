// CommandLine: the one table that declares every command of the `vdbrad` tool.
//
// Names, one-line docs and positional arguments live in a single table (Commands.cc); the options
// {name, default, example, doc, choices or range} of the commands the library serves (solve,
// solve-cloud, voxelize, render) are the library's (vdbrad/request/), the same the Python module
// takes. Parsing, `--help`, "did you mean" suggestions and
// the command table of docs/command-line.md (`vdbrad help --markdown`) are all generated from it,
// so they cannot drift. The whole command line is parsed, type-checked and range-checked before
// any heavy work starts: a typo or a value out of range fails in milliseconds and leaves no
// output. This file knows nothing of OpenVDB (it compiles fast).
#pragma once

#include "vdbrad/request/Request.h"

#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace vdbrad {
namespace cli {

/// A mistake in the command line (exit status 2).
class UsageError : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

/// A failure with a message ready for the user, already naming its file (exit status 1).
class UserError : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

class Arguments;

struct CommandSpec
{
    std::string name;
    std::string usage;                    ///< positional arguments, e.g. "NAME OUT.vdb"
    size_t minPositional = 0, maxPositional = 0;
    std::string doc;                      ///< one line
    std::vector<OptionSpec> options;
    std::vector<std::string> examples;    ///< full command lines
    std::function<int(const Arguments&)> run;
};

/// Parsed, type-checked arguments of one command: its positional arguments and its options
/// as a Request (read with the request's getters: a value given, else the default).
class Arguments
{
public:
    explicit Arguments(const CommandSpec& command);
    const CommandSpec& command() const { return *mCommand; }
    const std::vector<std::string>& positional() const { return mPositional; }
    const Request& request() const { return mRequest; }
    bool has(const std::string& name) const { return mRequest.has(name); }
    bool flag(const std::string& name) const { return mRequest.flag(name); }
    int getInt(const std::string& name) const { return mRequest.getInt(name); }
    double getFloat(const std::string& name) const { return mRequest.getFloat(name); }
    std::string getString(const std::string& name) const { return mRequest.getString(name); }

private:
    friend Arguments parseCommand(const CommandSpec&, const std::vector<std::string>&);
    const CommandSpec* mCommand;
    std::vector<std::string> mPositional;
    Request mRequest;
};

/// @brief Parse @a args (after the command name) against @a command.
/// Accepts `--name value`, `--name=value`, and `-` as a positional (standard input/output).
/// @throw UsageError with a suggestion for unknown options, missing values, bad numbers, values
///        outside an option's choices or range, wrong positional counts
Arguments parseCommand(const CommandSpec& command, const std::vector<std::string>& args);

/// Full help text of one command.
std::string commandHelp(const CommandSpec& command);
/// Overview of all commands.
std::string overviewHelp(const std::vector<CommandSpec>& commands);
/// Markdown table of every command and option (the command reference of docs/command-line.md).
std::string markdownReference(const std::vector<CommandSpec>& commands);

} // namespace cli
} // namespace vdbrad
