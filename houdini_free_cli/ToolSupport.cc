#include "ToolSupport.h"

#include "vdbrad/core/Version.h"
#include "vdbrad/distribute/Distribution.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <sys/stat.h>
#include <unistd.h>

namespace vdbrad {
namespace cli {

bool isStdin(const std::string& p) { return p == "-" || p == "stdin.vdb"; }
bool isStdout(const std::string& p) { return p == "-" || p == "stdout.vdb"; }
std::string inputLabel(const std::string& p) { return isStdin(p) ? "<stdin>" : p; }
std::string outputLabel(const std::string& p) { return isStdout(p) ? "<stdout>" : p; }

void
checkOutput(const std::string& out, const std::vector<std::string>& inputs, bool overwrite)
{
    if (isStdout(out)) {
        if (::isatty(STDOUT_FILENO) == 1) {
            throw UsageError("refusing to write VDB data to a terminal; redirect standard output "
                "or give a file name");
        }
        return;
    }
    struct stat so;
    if (::stat(out.c_str(), &so) == 0) {
        if (S_ISDIR(so.st_mode)) throw UserError(out + ": is a directory");
        for (const auto& in : inputs) {
            struct stat si;
            if (!isStdin(in) && ::stat(in.c_str(), &si) == 0 && si.st_dev == so.st_dev
                && si.st_ino == so.st_ino && !overwrite) {
                throw UsageError("output '" + out + "' is the input file; pass --overwrite to "
                    "replace it");
            }
        }
    }
    const size_t slash = out.find_last_of('/');
    const std::string dir = slash == std::string::npos ? "." : out.substr(0, slash + 1);
    struct stat sd;
    if (::stat(dir.c_str(), &sd) != 0 || !S_ISDIR(sd.st_mode)) {
        throw UserError(out + ": folder '" + dir + "' does not exist");
    }
}

VdbFile
readInput(const std::string& path)
{
    try {
        if (isStdin(path)) {
            if (job().distributed()) {
                // mpirun gives standard input to rank 0 alone.
                throw UsageError("under mpirun, give the input as a file (only rank 0 has "
                                 "standard input)");
            }
            if (::isatty(STDIN_FILENO) == 1) {
                throw UsageError("refusing to read VDB data from a terminal; pipe a file in");
            }
            return readVdbStream(std::cin);
        }
        return readVdbFile(path);
    } catch (const UsageError&) {
        throw;
    } catch (const std::exception& e) {
        throw UserError(inputLabel(path) + ": " + errorMessage(e));
    }
}

void
writeBytes(const std::string& bytes, const std::string& path)
{
    if (isStdout(path)) {
        // One write of complete bytes: a failure before this point leaves stdout empty.
        if (std::fwrite(bytes.data(), 1, bytes.size(), stdout) != bytes.size()
            || std::fflush(stdout) != 0) {
            throw UserError("<stdout>: write failed");
        }
        return;
    }
    forFile(path, [&] { writeFileAtomic(path, bytes); });
}

void
setCreator(VdbFile& file)
{
    file.metadata->insertMeta("creator", openvdb::StringMetadata(
        std::string("vdbrad ") + VDBRAD_VERSION_STRING));
}

void
writeOutput(const VdbFile& file, const std::string& path)
{
    writeBytes(forFile(outputLabel(path), [&] { return serializeVdb(file); }), path);
}

void
warn(const std::string& label, const std::string& what)
{
    if (job().rank() != 0) return;   // said once, by rank 0
    std::cerr << "vdbrad: warning: " << label << ": " << what << "\n";
}

void
describeReading(const Arguments& a, const std::string& label, const VdbFile& file,
    const std::string& surface, const std::string& density)
{
    if (!a.flag("verbose") || job().rank() != 0) return;
    // The builders meet the same grids next and report any error; here only what went right.
    std::vector<std::string> notes;
    try {
        notes = identifyRoles(file.grids, surface, density).notes;
    } catch (const std::exception&) {
        return;
    }
    for (const std::string& n : notes) std::cerr << "vdbrad: " << label << ": " << n << "\n";
}

} // namespace cli
} // namespace vdbrad
