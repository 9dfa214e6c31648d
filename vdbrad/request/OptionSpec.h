// OptionSpec: one option of a request, declared once: its name, type, default, an example, a
// one-line doc, and the values it accepts (choices or a range).
//
// The hosts generate everything from these declarations: the tool's parser, `--help` and the
// command reference of docs/command-line.md; the Python module's keyword arguments, their
// defaults and its docstrings (docs/python.md). This file knows nothing of OpenVDB.
#pragma once

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace vdbrad {

/// A bad option or combination of options; its message names them as the host spells them
/// (Request::spell). The tool says it in one line with exit status 2, Python raises ValueError.
class OptionError : public std::invalid_argument
{
public:
    using std::invalid_argument::invalid_argument;
};

/// Int: a whole number that fits an int. Float: a finite number that fits a float (most options
/// end up in floats; requests read them as doubles).
enum class OptionType { Flag, Int, Float, String };

struct OptionSpec
{
    std::string name;          ///< as the tool spells it, without the leading dashes
    OptionType type;
    /// As shown in help; empty: none. See describedDefault.
    std::string defaultValue;
    std::string example;       ///< a typical value, shown in help
    std::string doc;           ///< one line, with units; help adds the choices and the range
    /// The only values accepted (String or Int options); empty: any.
    std::vector<std::string> choices;
    /// The range of Int and Float values: [min, max], an exclusive end open.
    double min, max;
    bool minExclusive = false, maxExclusive = false;
    /// The default says what happens ("3/4 of RAM", "scene's") rather than being a value:
    /// Python's keyword then defaults to None.
    bool describedDefault = false;

    OptionSpec(std::string name, OptionType type, std::string defaultValue, std::string example,
        std::string doc);

    // Validation a request does itself, so a bad value fails before any work:
    // OptionSpec{...}.oneOf({"naive", "standard"}), OptionSpec{...}.within(1, 4096).
    OptionSpec oneOf(std::vector<std::string> values) const;
    OptionSpec atLeast(double lo) const;  ///< value >= lo
    OptionSpec above(double lo) const;    ///< value > lo
    OptionSpec atMost(double hi) const;   ///< value <= hi
    OptionSpec below(double hi) const;    ///< value < hi
    OptionSpec within(double lo, double hi) const { return atLeast(lo).atMost(hi); }
    OptionSpec described() const;         ///< see describedDefault

    /// The valid values in words ("naive or standard", "in [1, 4096]", ">= 0"); empty: any.
    std::string validValues() const;
    /// "[1, 4096]", "(-1, 1)", ">= 0"; empty without a range.
    std::string rangeText() const;
    /// The choices as "a, b or c", each word wrapped in @a quote.
    std::string choiceList(const std::string& quote = "") const;
    /// Empty if @a value reads as this option's type, else why not ("'abc' is not an integer").
    std::string typeError(const std::string& value) const;
    /// True if @a value (of the right type: typeError() empty) is among the valid values.
    bool accepts(const std::string& value) const;
};

/// Options listed one after the other.
std::vector<OptionSpec> concat(std::vector<OptionSpec> a, const std::vector<OptionSpec>& b);

/// The closest of @a candidates to @a word, if it is close enough to be a likely typo.
std::optional<std::string> suggest(const std::string& word,
    const std::vector<std::string>& candidates);

} // namespace vdbrad
