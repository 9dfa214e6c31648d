// fuzz_cli: libFuzzer target for the command-line parser (houdini_free_cli/CommandLine.h).
//
// The input becomes an argument vector: split on NUL bytes when it has any (so an argument may
// hold spaces), else on whitespace. It is parsed against every command of the tool's table, as
// runTool would after the command name. UsageError is the parser's documented answer to a bad
// command line; any other exception, a crash, a sanitizer report, a hang or a broken invariant
// (checked below, on every successful parse) is a finding.
#include "Seeds.h"

#include "houdini_free_cli/Commands.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

using namespace vdbrad;
using namespace vdbrad::cli;

std::vector<std::string>
splitArguments(const uint8_t* data, size_t size)
{
    const std::string s(reinterpret_cast<const char*>(data), size);
    const bool nul = s.find('\0') != std::string::npos;
    std::vector<std::string> args;
    std::string word;
    bool inWord = false;
    for (const char c : s) {
        const bool sep = nul ? c == '\0' : std::isspace(static_cast<unsigned char>(c)) != 0;
        if (sep) {
            // NUL-separated arguments may be empty ("" is a valid argv entry); spaces collapse.
            if (inWord || nul) args.push_back(word);
            word.clear();
            inWord = false;
        } else {
            word += c;
            inWord = true;
        }
    }
    if (inWord) args.push_back(word);
    return args;
}

void
require(bool ok, const CommandSpec& c, const char* what)
{
    if (ok) return;
    std::fprintf(stderr, "fuzz_cli: '%s': %s\n", c.name.c_str(), what);
    std::abort();
}

// What a successful parse promises the commands, which read options without re-checking them.
void
checkParsed(const CommandSpec& c, const Arguments& a)
{
    require(&a.command() == &c, c, "wrong command");
    const size_t n = a.positional().size();
    require(n >= c.minPositional && n <= c.maxPositional, c, "positional count out of range");
    for (const OptionSpec& o : c.options) {
        const bool given = a.has(o.name);
        require(a.flag(o.name) == given, c, "flag() disagrees with has()");
        const std::string value = a.getString(o.name);
        if (!given) {
            require(value == o.defaultValue, c, "absent option does not give its default");
            continue;
        }
        require(o.accepts(value), c, "accepted a value outside the option's choices or range");
        switch (o.type) {
            case OptionType::Flag: require(value == "1", c, "flag value"); break;
            case OptionType::String: break;
            case OptionType::Int: {
                errno = 0;
                char* end = nullptr;
                const long long v = std::strtoll(value.c_str(), &end, 10);
                require(!value.empty() && *end == '\0' && errno == 0, c, "accepted a bad integer");
                require(v == a.getInt(o.name), c, "getInt() does not return the value given");
                break;
            }
            case OptionType::Float:
                require(std::isfinite(a.getFloat(o.name)), c, "accepted a non-finite number");
                break;
        }
    }
}

std::string
join(const std::vector<std::string>& words, char separator)
{
    std::string s;
    for (size_t i = 0; i < words.size(); ++i) s += (i ? std::string(1, separator) : "") + words[i];
    return s;
}

// Seeds: the table's own examples, then every option with its example value, in both spellings
// and both separators.
std::vector<std::string>
seeds()
{
    std::vector<std::string> out;
    for (const CommandSpec& c : commands()) {
        for (const std::string& e : c.examples) {
            // "vdbrad make cornell - | vdbrad info -": the words after "vdbrad NAME", to a pipe.
            const std::string head = "vdbrad " + c.name + " ";
            const size_t at = e.find(head);
            if (at == std::string::npos) continue;
            const std::string rest = e.substr(at + head.size());
            out.push_back(rest.substr(0, rest.find_first_of("|&")));
        }
        const std::vector<std::string> positional(c.minPositional, "in.vdb");
        for (const OptionSpec& o : c.options) {
            std::vector<std::string> words = positional, inlined = positional;
            words.push_back("--" + o.name);
            inlined.push_back("--" + o.name);
            if (o.type != OptionType::Flag) {
                const std::string v = o.example.empty() ? "x" : o.example;
                words.push_back(v);
                inlined.back() += "=" + v;
            }
            out.push_back(join(words, ' '));
            out.push_back(join(inlined, '\0'));
        }
    }
    return out;
}

} // namespace

extern "C" int
LLVMFuzzerInitialize(int*, char***)
{
    vdbrad::fuzz::writeSeeds(seeds());
    return 0;
}

extern "C" int
LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    const std::vector<std::string> args = splitArguments(data, size);
    std::vector<std::string> names;
    for (const CommandSpec& c : commands()) {
        names.push_back(c.name);
        try {
            const Arguments a = parseCommand(c, args);
            checkParsed(c, a);
        } catch (const UsageError&) {
            // The documented answer to a bad command line (exit status 2).
        }
    }
    // runTool's "did you mean" for an unknown command name.
    if (!args.empty()) (void)suggest(args[0], names);
    return 0;
}
