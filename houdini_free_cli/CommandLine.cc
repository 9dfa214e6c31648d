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

// Edit distance counting a swap of two neighbouring letters ("mkae") as one typo.
size_t
editDistance(const std::string& a, const std::string& b)
{
    // One flat table: every unknown option is measured against every option of the command.
    const size_t w = b.size() + 1;
    std::vector<size_t> d((a.size() + 1) * w);
    auto at = [&](size_t i, size_t j) -> size_t& { return d[i * w + j]; };
    for (size_t i = 0; i <= a.size(); ++i) at(i, 0) = i;
    for (size_t j = 0; j <= b.size(); ++j) at(0, j) = j;
    for (size_t i = 1; i <= a.size(); ++i) {
        for (size_t j = 1; j <= b.size(); ++j) {
            at(i, j) = std::min({at(i - 1, j) + 1, at(i, j - 1) + 1,
                at(i - 1, j - 1) + (a[i - 1] == b[j - 1] ? 0 : 1)});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
                at(i, j) = std::min(at(i, j), at(i - 2, j - 2) + 1);
            }
        }
    }
    return at(a.size(), b.size());
}

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

// Parse a whole string as a number; reject trailing junk, NaN and infinities.
bool
parseNumber(const std::string& s, OptionType type, std::string& error)
{
    if (s.empty()) { error = "empty value"; return false; }
    errno = 0;
    char* end = nullptr;
    if (type == OptionType::Int) {
        const long long v = std::strtoll(s.c_str(), &end, 10);
        if (*end != '\0') { error = "'" + s + "' is not an integer"; return false; }
        if (errno == ERANGE || v > std::numeric_limits<int>::max()
            || v < std::numeric_limits<int>::min()) {
            error = "'" + s + "' is out of range";
            return false;
        }
        return true;
    }
    const double v = std::strtod(s.c_str(), &end);
    if (*end != '\0') { error = "'" + s + "' is not a number"; return false; }
    if (!std::isfinite(v) || errno == ERANGE) {
        error = "'" + s + "' is not a finite number";
        return false;
    }
    if (std::abs(v) > double(std::numeric_limits<float>::max())) {
        error = "'" + s + "' is out of range";
        return false;
    }
    return true;
}

// A bound as the user would type it: integers without an exponent (1000000, not 1e+06).
std::string
formatBound(double v, OptionType type)
{
    if (type == OptionType::Int) return std::to_string(std::llround(v));
    std::ostringstream os;
    os << v;
    return os.str();
}

// "[1, 4096]", "(-1, 1)", ">= 0", "> 0", "<= 1"; empty without a range.
std::string
rangeText(const OptionSpec& o)
{
    const bool low = o.min > -std::numeric_limits<double>::infinity();
    const bool high = o.max < std::numeric_limits<double>::infinity();
    const std::string lo = formatBound(o.min, o.type), hi = formatBound(o.max, o.type);
    if (low && high) {
        return (o.minExclusive ? "(" : "[") + lo + ", " + hi + (o.maxExclusive ? ")" : "]");
    }
    if (low) return (o.minExclusive ? "> " : ">= ") + lo;
    if (high) return (o.maxExclusive ? "< " : "<= ") + hi;
    return "";
}

// @a o with its lower (or upper) bound set to @a value.
OptionSpec
withBound(OptionSpec o, bool lower, double value, bool exclusive)
{
    (lower ? o.min : o.max) = value;
    (lower ? o.minExclusive : o.maxExclusive) = exclusive;
    return o;
}

// "a", "a or b", "a, b or c", each word wrapped in @a quote.
std::string
listChoices(const std::vector<std::string>& choices, const std::string& quote)
{
    std::string s;
    for (size_t i = 0; i < choices.size(); ++i) {
        if (i > 0) s += i + 1 == choices.size() ? " or " : ", ";
        s += quote + choices[i] + quote;
    }
    return s;
}

} // namespace

std::optional<std::string>
suggest(const std::string& word, const std::vector<std::string>& candidates)
{
    std::optional<std::string> best;
    size_t bestDistance = std::numeric_limits<size_t>::max();
    const size_t tolerance = std::max<size_t>(1, word.size() / 3);
    for (const auto& c : candidates) {
        // The distance is at least the difference in length: a candidate that far off cannot be
        // suggested, so skip the table (found by fuzz_cli: a 100 KB argument took ~1 s).
        const size_t gap = word.size() > c.size() ? word.size() - c.size() : c.size() - word.size();
        size_t d = gap > tolerance ? gap : editDistance(word, c);
        // A prefix ("--res" for "--resolution") is as good as a one-letter typo.
        if (!word.empty() && c.compare(0, word.size(), word) == 0) d = std::min<size_t>(d, 1);
        if (d < bestDistance) { bestDistance = d; best = c; }
    }
    if (best && bestDistance <= tolerance) return best;
    return std::nullopt;
}

OptionSpec::OptionSpec(std::string name, OptionType type, std::string defaultValue,
    std::string example, std::string doc)
    : name(std::move(name))
    , type(type)
    , defaultValue(std::move(defaultValue))
    , example(std::move(example))
    , doc(std::move(doc))
    , min(-std::numeric_limits<double>::infinity())
    , max(std::numeric_limits<double>::infinity())
{
}

OptionSpec
OptionSpec::oneOf(std::vector<std::string> values) const
{
    OptionSpec o = *this;
    o.choices = std::move(values);
    return o;
}

OptionSpec OptionSpec::atLeast(double lo) const { return withBound(*this, true, lo, false); }
OptionSpec OptionSpec::above(double lo) const { return withBound(*this, true, lo, true); }
OptionSpec OptionSpec::atMost(double hi) const { return withBound(*this, false, hi, false); }
OptionSpec OptionSpec::below(double hi) const { return withBound(*this, false, hi, true); }

std::string
OptionSpec::validValues() const
{
    if (!choices.empty()) return listChoices(choices, "");
    const std::string range = rangeText(*this);
    return !range.empty() && (range[0] == '[' || range[0] == '(') ? "in " + range : range;
}

bool
OptionSpec::accepts(const std::string& value) const
{
    if (!choices.empty()) {
        // Int choices compare as numbers: "026" is 26.
        return std::any_of(choices.begin(), choices.end(), [&](const std::string& c) {
            return type == OptionType::Int ? std::strtoll(c.c_str(), nullptr, 10)
                == std::strtoll(value.c_str(), nullptr, 10) : c == value;
        });
    }
    if (type != OptionType::Int && type != OptionType::Float) return true;
    const double v = std::strtod(value.c_str(), nullptr);
    return (minExclusive ? v > min : v >= min) && (maxExclusive ? v < max : v <= max);
}

const OptionSpec&
Arguments::spec(const std::string& name) const
{
    for (const auto& o : mCommand->options) {
        if (o.name == name) return o;
    }
    // A programming error in a command, not a user mistake.
    throw std::logic_error("command '" + mCommand->name + "' has no option --" + name);
}

bool
Arguments::has(const std::string& name) const
{
    spec(name);
    return mValues.count(name) != 0;
}

bool
Arguments::flag(const std::string& name) const
{
    return has(name);
}

std::string
Arguments::getString(const std::string& name) const
{
    const OptionSpec& o = spec(name);
    auto it = mValues.find(name);
    return it != mValues.end() ? it->second : o.defaultValue;
}

int
Arguments::getInt(const std::string& name) const
{
    return int(std::strtol(getString(name).c_str(), nullptr, 10));
}

double
Arguments::getFloat(const std::string& name) const
{
    return std::strtod(getString(name).c_str(), nullptr);
}

Arguments
parseCommand(const CommandSpec& command, const std::vector<std::string>& args)
{
    Arguments out;
    out.mCommand = &command;
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
            out.mValues[name] = "1";
            continue;
        }
        if (!inlineValue) {
            if (i + 1 >= args.size()) {
                throw UsageError("option --" + name + " needs a value, e.g. --" + name + " "
                    + spec->example);
            }
            value = args[++i];
        }
        std::string error;
        if ((spec->type == OptionType::Int || spec->type == OptionType::Float)
            && !parseNumber(value, spec->type, error)) {
            throw UsageError("option --" + name + ": " + error);
        }
        if (!spec->accepts(value)) {
            const std::string shown = spec->type == OptionType::String ? "'" + value + "'" : value;
            throw UsageError("--" + name + " must be " + spec->validValues() + ", got " + shown);
        }
        out.mValues[name] = value;
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
                   << (o.choices.empty() ? rangeText(o) : listChoices(o.choices, "`")) << " | "
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
