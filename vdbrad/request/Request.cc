#include "vdbrad/request/Request.h"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace vdbrad {

Request::Request(std::string command, const std::vector<OptionSpec>& options, Spelling spelling)
    : mCommand(std::move(command))
    , mOptions(&options)
    , mSpelling(spelling)
{
}

std::string
Request::spell(const std::string& name) const
{
    if (mSpelling == Spelling::CommandLine) return "--" + name;
    std::string s = name;
    for (char& c : s) {
        if (c == '-') c = '_';
    }
    return s;
}

const OptionSpec*
Request::find(const std::string& name) const
{
    for (const OptionSpec& o : *mOptions) {
        if (o.name == name) return &o;
    }
    return nullptr;
}

const OptionSpec&
Request::spec(const std::string& name) const
{
    if (const OptionSpec* o = find(name)) return *o;
    // A programming error in a host or a request, not a user mistake.
    throw std::logic_error("'" + mCommand + "' has no option " + name);
}

void
Request::set(const std::string& name, const std::string& text)
{
    const OptionSpec* o = find(name);
    if (!o) {
        std::vector<std::string> names;
        for (const OptionSpec& s : *mOptions) names.push_back(spell(s.name));
        std::string msg = "unknown option '" + spell(name) + "' for '" + mCommand + "'";
        if (auto s = suggest(spell(name), names)) msg += "; did you mean '" + *s + "'?";
        fail(msg);
    }
    if (o->type == OptionType::Flag) {
        mValues[name] = "1";
        return;
    }
    const std::string error = o->typeError(text);
    if (!error.empty()) fail("option " + spell(name) + ": " + error);
    if (!o->accepts(text)) {
        const std::string shown = o->type == OptionType::String ? "'" + text + "'" : text;
        fail(spell(name) + " must be " + o->validValues() + ", got " + shown);
    }
    mValues[name] = text;
}

bool
Request::has(const std::string& name) const
{
    spec(name);
    return mValues.count(name) != 0;
}

std::string
Request::getString(const std::string& name) const
{
    const OptionSpec& o = spec(name);
    const auto it = mValues.find(name);
    return it != mValues.end() ? it->second : o.defaultValue;
}

int
Request::getInt(const std::string& name) const
{
    return int(std::strtol(getString(name).c_str(), nullptr, 10));
}

double
Request::getFloat(const std::string& name) const
{
    return std::strtod(getString(name).c_str(), nullptr);
}

std::vector<double>
Request::numbers(const std::string& name, size_t count, const std::string& shape) const
{
    const std::string text = getString(name);
    std::vector<double> values;
    std::istringstream is(text);
    for (std::string item; std::getline(is, item, ',');) {
        char* end = nullptr;
        const double v = std::strtod(item.c_str(), &end);
        if (item.empty() || *end != '\0' || !std::isfinite(v)) {
            fail(spell(name) + ": '" + item + "' is not a number (expected " + shape + ")");
        }
        values.push_back(v);
    }
    if (count == 0 ? values.empty() : values.size() != count) {
        fail(spell(name) + " needs " + (count ? std::to_string(count) + " " : "")
            + "comma-separated numbers (" + shape + "), got '" + text + "'");
    }
    return values;
}

openvdb::math::Vec3d
Request::colour(const std::string& name) const
{
    const std::vector<double> v = numbers(name, 0, "one number or r,g,b");
    if (v.size() != 1 && v.size() != 3) {
        fail(spell(name) + " needs one number (grey) or three (r,g,b), got '" + getString(name)
            + "'");
    }
    const openvdb::Vec3d c = v.size() == 1 ? openvdb::Vec3d(v[0]) : openvdb::Vec3d(v[0], v[1], v[2]);
    if (c[0] < 0.0 || c[1] < 0.0 || c[2] < 0.0) fail(spell(name) + " must be >= 0");
    return c;
}

double
Request::bytes(const std::string& name, bool zero) const
{
    const std::string text = getString(name);
    char* end = nullptr;
    double v = std::strtod(text.c_str(), &end);
    std::string unit(end ? end : "");
    if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b')) unit.pop_back();
    if (unit.size() > 1 && (unit.back() == 'i' || unit.back() == 'I')) unit.pop_back();
    const std::string units = "KMGT";
    if (unit.size() == 1 && units.find(char(std::toupper(unit[0]))) != std::string::npos) {
        v *= std::pow(1024.0, double(units.find(char(std::toupper(unit[0]))) + 1));
    } else if (!unit.empty()) {
        v = -1.0;
    }
    if (end == text.c_str() || !(v > 0.0 || (zero && v == 0.0)) || !std::isfinite(v)) {
        fail(spell(name) + ": '" + text + "' is not a size (e.g. 8G, 512M, 1000000"
            + (zero ? ", 0" : "") + ")");
    }
    return v;
}

std::optional<int>
Request::autoOr(const std::string& name, long lo, long hi, const std::string& what) const
{
    const std::string text = getString(name);
    if (text == "auto") return std::nullopt;
    char* end = nullptr;
    const long v = std::strtol(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0' || v < lo || v > hi) {
        fail(spell(name) + " must be auto or " + what + " in [" + std::to_string(lo) + ", "
            + std::to_string(hi) + "], got '" + text + "'");
    }
    return int(v);
}

void
Request::fail(const std::string& message) const
{
    throw OptionError(message);
}

void
Request::missingMeaning(const std::string& name) const
{
    throw std::logic_error(spell(name) + " " + getString(name) + " has no meaning");
}

} // namespace vdbrad
