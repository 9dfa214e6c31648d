#include "CommandLine.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <utility>

namespace vdbrad {
namespace cli {

namespace {

const char*
typeName(OptionType t)
{
    switch (t) {
        case OptionType::Flag: return "";
        case OptionType::Int: return "INT";
        case OptionType::Float: return "X";
        case OptionType::String: return "S";
    }
    return "";
}

} // namespace

Arguments::Arguments(const CommandSpec& command)
    : mCommand(&command)
    , mRequest(command.name, command.options)
{
}

Arguments
parseCommand(const CommandSpec& command, const std::vector<std::string>& args)
{
    Arguments out(command);
    std::vector<std::string> optionNames;
    for (const auto& o : command.options) optionNames.push_back("--" + o.name);

    for (size_t i = 0; i < args.size(); ++i) {
        const std::string& a = args[i];
        if (a.size() < 2 || a[0] != '-' || a == "-") {
            out.mPositional.push_back(a);
            continue;
        }
        std::string name = a.substr(a[1] == '-' ? 2 : 1), value;
        bool inlineValue = false;
        if (const size_t eq = name.find('='); eq != std::string::npos) {
            value = name.substr(eq + 1);
            name = name.substr(0, eq);
            inlineValue = true;
        }
        const OptionSpec* spec = nullptr;
        for (const auto& o : command.options) {
            if (o.name == name) spec = &o;
        }
        if (!spec) {
            std::string msg = "unknown option '" + a + "' for '" + command.name + "'";
            if (auto s = suggest("--" + name, optionNames)) msg += "; did you mean '" + *s + "'?";
            throw UsageError(msg);
        }
        if (spec->type == OptionType::Flag) {
            if (inlineValue) throw UsageError("option --" + name + " takes no value");
            out.mRequest.set(name, "");
            continue;
        }
        if (!inlineValue) {
            if (i + 1 >= args.size()) {
                throw UsageError("option --" + name + " needs a value, e.g. --" + name + " "
                    + spec->example);
            }
            value = args[++i];
        }
        try {
            out.mRequest.set(name, value);
        } catch (const OptionError& e) {
            throw UsageError(e.what());
        }
    }
    const size_t n = out.mPositional.size();
    if (n < command.minPositional || n > command.maxPositional) {
        std::ostringstream os;
        os << "'" << command.name << "' takes " << command.usage << " (" << n
           << " argument" << (n == 1 ? "" : "s") << " given); see 'vdbrad " << command.name
           << " --help'";
        throw UsageError(os.str());
    }
    return out;
}

std::string
commandHelp(const CommandSpec& c)
{
    std::ostringstream os;
    os << "usage: vdbrad " << c.name << " " << c.usage << " [options]\n\n" << c.doc << "\n";
    if (!c.options.empty()) {
        os << "\noptions:\n";
        for (const auto& o : c.options) {
            // Choices stand in the head ("--lines naive|standard"), a range after the doc.
            std::string head = "  --" + o.name;
            if (!o.choices.empty()) {
                head += " " + o.choices[0];
                for (size_t i = 1; i < o.choices.size(); ++i) head += "|" + o.choices[i];
            } else if (o.type != OptionType::Flag) {
                head += std::string(" ") + typeName(o.type);
            }
            os << head;
            if (head.size() < 24) os << std::string(24 - head.size(), ' ');
            else os << "\n" << std::string(24, ' ');
            os << o.doc;
            std::string notes = o.choices.empty() ? o.validValues() : "";
            if (!o.defaultValue.empty()) {
                notes += (notes.empty() ? "" : "; ") + std::string("default ") + o.defaultValue;
            }
            if (!notes.empty()) os << " (" << notes << ")";
            os << "\n";
        }
    }
    if (!c.examples.empty()) {
        os << "\nexamples:\n";
        for (const auto& e : c.examples) os << "  " << e << "\n";
    }
    return os.str();
}

std::string
overviewHelp(const std::vector<CommandSpec>& commands)
{
    std::ostringstream os;
    os << "usage: vdbrad COMMAND [arguments] [options]\n\n"
       << "Voxel radiosity on OpenVDB grids. '-' (or stdin.vdb / stdout.vdb) reads standard input\n"
       << "or writes standard output, so commands chain with pipes.\n\ncommands:\n";
    for (const auto& c : commands) {
        os << "  " << c.name << std::string(c.name.size() < 10 ? 10 - c.name.size() : 1, ' ')
           << c.doc << "\n";
    }
    os << "\n'vdbrad COMMAND --help' describes a command and its options.\n";
    return os.str();
}

std::string
markdownReference(const std::vector<CommandSpec>& commands)
{
    std::ostringstream os;
    for (const auto& c : commands) {
        os << "### `vdbrad " << c.name << " " << c.usage << "`\n\n" << c.doc << "\n\n";
        if (!c.options.empty()) {
            os << "| option | values | default | example | meaning |\n|---|---|---|---|---|\n";
            auto code = [](const std::string& s) { return s.empty() ? s : "`" + s + "`"; };
            for (const auto& o : c.options) {
                // A '|' in a doc ("max|B' - B|") would split its cell.
                std::string doc;
                for (const char ch : o.doc) {
                    doc += ch == '|' ? std::string("\\|") : std::string(1, ch);
                }
                os << "| `--" << o.name << "` | "
                   << (o.choices.empty() ? o.rangeText() : o.choiceList("`")) << " | "
                   << code(o.defaultValue) << " | " << code(o.example) << " | " << doc << " |\n";
            }
            os << "\n";
        }
        for (const auto& e : c.examples) os << "    " << e << "\n";
        if (!c.examples.empty()) os << "\n";
    }
    return os.str();
}

} // namespace cli
} // namespace vdbrad
