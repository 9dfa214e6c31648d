// CommandLine: the one table that declares every command of the `vdbrad` tool.
//
// Names, one-line docs, positional arguments and options {name, default, example, doc, choices or
// range} live in a single table (Commands.cc). Parsing, `--help`, "did you mean" suggestions and
// the command table of docs/command-line.md (`vdbrad help --markdown`) are all generated from it,
// so they cannot drift. The whole command line is parsed, type-checked and range-checked before
// any heavy work starts: a typo or a value out of range fails in milliseconds and leaves no
// output. This file knows nothing of OpenVDB (it compiles fast).
#pragma once

#include <functional>
#include <map>
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

/// Int: a whole number that fits an int. Float: a finite number that fits a float (most options
/// end up in floats; the commands read them as doubles).
enum class OptionType { Flag, Int, Float, String };

struct OptionSpec
{
    std::string name;          ///< without the leading dashes
    OptionType type;
    std::string defaultValue;  ///< as shown in help; empty: none
    std::string example;       ///< a typical value, shown in help
    std::string doc;           ///< one line, with units; help adds the choices and the range
    /// The only values accepted (String or Int options); empty: any.
    std::vector<std::string> choices;
    /// The range of Int and Float values: [min, max], an exclusive end open.
    double min, max;
    bool minExclusive = false, maxExclusive = false;

    OptionSpec(std::string name, OptionType type, std::string defaultValue, std::string example,
        std::string doc);

    // Validation the parser does itself, so a bad value fails before any command runs:
    // OptionSpec{...}.oneOf({"naive", "standard"}), OptionSpec{...}.within(1, 4096).
    OptionSpec oneOf(std::vector<std::string> values) const;
    OptionSpec atLeast(double lo) const;  ///< value >= lo
    OptionSpec above(double lo) const;    ///< value > lo
    OptionSpec atMost(double hi) const;   ///< value <= hi
    OptionSpec below(double hi) const;    ///< value < hi
    OptionSpec within(double lo, double hi) const { return atLeast(lo).atMost(hi); }

    /// The valid values in words ("naive or standard", "in [1, 4096]", ">= 0"); empty: any.
    std::string validValues() const;
    /// True if @a value (a number already parsed, for Int and Float) is valid.
    bool accepts(const std::string& value) const;
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

/// Parsed, type-checked arguments of one command.
class Arguments
{
public:
    const CommandSpec& command() const { return *mCommand; }
    const std::vector<std::string>& positional() const { return mPositional; }
    bool has(const std::string& name) const;         ///< given on the command line
    bool flag(const std::string& name) const;
    int getInt(const std::string& name) const;        ///< given value, else the default
    double getFloat(const std::string& name) const;
    std::string getString(const std::string& name) const;

private:
    friend Arguments parseCommand(const CommandSpec&, const std::vector<std::string>&);
    const CommandSpec* mCommand = nullptr;
    std::vector<std::string> mPositional;
    std::map<std::string, std::string> mValues;
    const OptionSpec& spec(const std::string& name) const;
};

/// @brief Parse @a args (after the command name) against @a command.
/// Accepts `--name value`, `--name=value`, and `-` as a positional (standard input/output).
/// @throw UsageError with a suggestion for unknown options, missing values, bad numbers, values
///        outside an option's choices or range, wrong positional counts
Arguments parseCommand(const CommandSpec& command, const std::vector<std::string>& args);

/// The closest of @a candidates to @a word, if it is close enough to be a likely typo.
std::optional<std::string> suggest(const std::string& word,
    const std::vector<std::string>& candidates);

/// Full help text of one command.
std::string commandHelp(const CommandSpec& command);
/// Overview of all commands.
std::string overviewHelp(const std::vector<CommandSpec>& commands);
/// Markdown table of every command and option (the command reference of docs/command-line.md).
std::string markdownReference(const std::vector<CommandSpec>& commands);

} // namespace cli
} // namespace vdbrad
