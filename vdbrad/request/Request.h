// Request: the options a host was given for one command, checked against its OptionSpecs.
//
// A host (the tool's command line, a Python call) sets what the user gave, as text; the
// request checks each value's type and range as it is set and answers every read with the
// value given or the declared default, so a default is written once, in the spec. Errors are
// OptionErrors that name options as the host spells them: `--max-memory` on the command line,
// `max_memory` in Python.
#pragma once

#include "vdbrad/request/OptionSpec.h"

#include <openvdb/math/Vec3.h>

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace vdbrad {

enum class Spelling { CommandLine, Python };

class Request
{
public:
    /// @a command names the request in messages; @a options must outlive it.
    Request(std::string command, const std::vector<OptionSpec>& options,
        Spelling spelling = Spelling::CommandLine);

    const std::string& command() const { return mCommand; }
    const std::vector<OptionSpec>& options() const { return *mOptions; }
    Spelling spelling() const { return mSpelling; }
    /// The option @a name as the user wrote it: "--max-memory" or "max_memory".
    std::string spell(const std::string& name) const;
    /// @brief The declaration of @a name, or null if the command has no such option.
    const OptionSpec* find(const std::string& name) const;

    /// @brief Give option @a name the value @a text (a Flag: any text sets it).
    /// @throw OptionError for an unknown option (with a likely one), a value of the wrong type or
    ///        outside the option's choices or range
    void set(const std::string& name, const std::string& text);

    bool has(const std::string& name) const;          ///< given
    bool flag(const std::string& name) const { return has(name); }
    std::string getString(const std::string& name) const;   ///< given, else the default
    int getInt(const std::string& name) const;
    double getFloat(const std::string& name) const;

    // Values with more shape than one word, read and checked here so every host reads them
    // alike ("60,30" or a Python tuple alike).
    /// @brief "a,b,c" as exactly @a count finite numbers (0: one or more); @a shape says what
    /// they are in the message.
    std::vector<double> numbers(const std::string& name, size_t count,
        const std::string& shape) const;
    /// A linear colour: one number (grey) or "r,g,b", each >= 0.
    openvdb::math::Vec3d colour(const std::string& name) const;
    /// A size in bytes ("512M", "8G", "1000000"; binary units), > 0 or, if @a zero, >= 0.
    double bytes(const std::string& name, bool zero) const;
    /// "auto" (nullopt) or a whole number in [lo, hi] (@a what it counts).
    std::optional<int> autoOr(const std::string& name, long lo, long hi,
        const std::string& what) const;
    /// @brief The given word mapped through @a values; a word the spec accepts but @a values
    /// lacks is a programming error.
    template<typename T>
    T choice(const std::string& name, const std::map<std::string, T>& values) const
    {
        const auto it = values.find(getString(name));
        if (it == values.end()) missingMeaning(name);
        return it->second;
    }

    /// @throw OptionError with @a message (its options spelt with spell()).
    [[noreturn]] void fail(const std::string& message) const;

private:
    [[noreturn]] void missingMeaning(const std::string& name) const;
    const OptionSpec& spec(const std::string& name) const;

    std::string mCommand;
    const std::vector<OptionSpec>* mOptions;
    Spelling mSpelling;
    std::map<std::string, std::string> mValues;
};

} // namespace vdbrad
