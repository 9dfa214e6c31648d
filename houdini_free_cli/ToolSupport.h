// ToolSupport: what several commands of the tool share: standard streams and files, error
// labels, number formats and the options every scene command reads.
#pragma once

#include "CommandLine.h"

#include "vdbrad/core/Errors.h"
#include "vdbrad/core/GridIO.h"
#include "vdbrad/core/TextFormat.h"
#include "vdbrad/scene/Scene.h"

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace vdbrad {

class Distribution;

namespace cli {

// ---- the MPI job ------------------------------------------------------------------------------

/// The MPI job the tool runs in: what runTool() was given (main() joins it), else this process
/// alone. Solves take it through their options' `ranks`.
const Distribution& job();

// ---- standard streams and files ----------------------------------------------------------------

/// "-" and vdb_tool's "stdin.vdb" / "stdout.vdb" name the standard streams.
bool isStdin(const std::string& path);
bool isStdout(const std::string& path);
/// The name an error gives the file: "<stdin>", "<stdout>" or the path.
std::string inputLabel(const std::string& path);
std::string outputLabel(const std::string& path);

/// @brief Checks on an output made before any heavy work, so a bad command line fails in
/// milliseconds: no binary to a terminal, no missing folder, no input overwritten unless
/// @a overwrite.
void checkOutput(const std::string& out, const std::vector<std::string>& inputs, bool overwrite);

/// Read a .vdb file or standard input; errors name the input.
VdbFile readInput(const std::string& path);

/// @brief Write @a bytes to the file @a path (atomically) or to standard output, in one piece:
/// a failure before this leaves no partial output.
void writeBytes(const std::string& bytes, const std::string& path);
/// Name this vdbrad and its version as the creator of a file it made from scratch.
void setCreator(VdbFile& file);
/// Write @a file as .vdb bytes (see writeBytes).
void writeOutput(const VdbFile& file, const std::string& path);

/// A warning line on stderr, naming what it is about.
void warn(const std::string& label, const std::string& what);

/// @brief With --verbose, a line on stderr for each grid of @a file the scene contract read other
/// than as written (GridRoles::notes: double as float, `Cd` as the albedo, half storage).
void describeReading(const Arguments& a, const std::string& label, const VdbFile& file,
    const std::string& surface, const std::string& density);

/// Runs @a f, turning library errors into one user line naming @a label.
template<typename F>
auto
forFile(const std::string& label, F&& f) -> decltype(f())
{
    try {
        return f();
    } catch (const Cancelled&) {
        throw;
    } catch (const CheckpointError&) {
        throw;   // names its own file
    } catch (const UserError&) {
        throw;
    } catch (const UsageError&) {
        throw;
    } catch (const OptionError&) {
        throw;   // a command-line mistake found once the input was read (exit status 2)
    } catch (const std::exception& e) {
        throw UserError(label + ": " + errorMessage(e));
    }
}

} // namespace cli
} // namespace vdbrad
