#include "vdbrad/request/OptionSpec.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <utility>

namespace vdbrad {

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

// A bound as the user would type it: integers without an exponent (1000000, not 1e+06).
std::string
formatBound(double v, OptionType type)
{
    if (type == OptionType::Int) return std::to_string(std::llround(v));
    std::ostringstream os;
    os << v;
    return os.str();
}

// @a o with its lower (or upper) bound set to @a value.
OptionSpec
withBound(OptionSpec o, bool lower, double value, bool exclusive)
{
    (lower ? o.min : o.max) = value;
    (lower ? o.minExclusive : o.maxExclusive) = exclusive;
    return o;
}

} // namespace

std::vector<OptionSpec>
concat(std::vector<OptionSpec> a, const std::vector<OptionSpec>& b)
{
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

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

OptionSpec
OptionSpec::described() const
{
    OptionSpec o = *this;
    o.describedDefault = true;
    return o;
}

std::string
OptionSpec::rangeText() const
{
    const bool low = min > -std::numeric_limits<double>::infinity();
    const bool high = max < std::numeric_limits<double>::infinity();
    const std::string lo = formatBound(min, type), hi = formatBound(max, type);
    if (low && high) return (minExclusive ? "(" : "[") + lo + ", " + hi + (maxExclusive ? ")" : "]");
    if (low) return (minExclusive ? "> " : ">= ") + lo;
    if (high) return (maxExclusive ? "< " : "<= ") + hi;
    return "";
}

std::string
OptionSpec::choiceList(const std::string& quote) const
{
    std::string s;
    for (size_t i = 0; i < choices.size(); ++i) {
        if (i > 0) s += i + 1 == choices.size() ? " or " : ", ";
        s += quote + choices[i] + quote;
    }
    return s;
}

std::string
OptionSpec::validValues() const
{
    if (!choices.empty()) return choiceList();
    const std::string range = rangeText();
    return !range.empty() && (range[0] == '[' || range[0] == '(') ? "in " + range : range;
}

// A whole string as a number: no trailing junk, NaN or infinities.
std::string
OptionSpec::typeError(const std::string& s) const
{
    if (type != OptionType::Int && type != OptionType::Float) return "";
    if (s.empty()) return "empty value";
    errno = 0;
    char* end = nullptr;
    if (type == OptionType::Int) {
        const long long v = std::strtoll(s.c_str(), &end, 10);
        if (*end != '\0') return "'" + s + "' is not an integer";
        if (errno == ERANGE || v > std::numeric_limits<int>::max()
            || v < std::numeric_limits<int>::min()) {
            return "'" + s + "' is out of range";
        }
        return "";
    }
    const double v = std::strtod(s.c_str(), &end);
    if (*end != '\0') return "'" + s + "' is not a number";
    if (!std::isfinite(v) || errno == ERANGE) return "'" + s + "' is not a finite number";
    if (std::abs(v) > double(std::numeric_limits<float>::max())) return "'" + s + "' is out of range";
    return "";
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

} // namespace vdbrad
