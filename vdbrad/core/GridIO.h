// GridIO: reading and writing whole `.vdb` files, from paths or streams, all-or-nothing.
//
// Reading: the bytes are read completely first, the header is checked, then OpenVDB parses them
// from memory with delayed loading off. So a pipe reads the same as a file, no
// /tmp/openvdb_temp_* copy is left behind, corrupt voxel data is found now rather than later,
// and a file truncated inside its header (which OpenVDB 10 reads as "0 grids") is an error.
// Crash guard: OpenVDB 10's reader trusts sizes and masks in the file, so some corrupt files
// crash it (segfaults, aborts, heap corruption; fixed in part in OpenVDB 11). vdbrad reads files
// from other tools, unattended, so the bytes are first parsed in a forked child (CrashGuard.h:
// one thread, silent, with limits on memory, CPU and wall-clock time), which reads every leaf
// buffer, frees everything and exits; the parent parses only if the child succeeded, and reports
// a child's crash or error as an IoError. Cost: the child's parse (one thread, in a fresh
// process) plus the fork, a few plain parses (docs/journal/2026-12-01-crash-guard.md), where
// solving the scene takes minutes. Where fork() or waitpid() are unavailable (no process left,
// SIGCHLD ignored by the application), the bytes are parsed unguarded.
// Writing: the file is serialised in memory, written to a temporary file in the destination's
// folder, flushed and renamed over the destination: a failure (full disk, cancel) leaves the
// destination as it was and no partial file. Standard output gets the same bytes in one go.
#pragma once

#include <openvdb/openvdb.h>

#include <iosfwd>
#include <string>

namespace vdbrad {

/// The contents of one `.vdb` file: its grids and its file-level metadata (e.g. `creator`).
struct VdbFile
{
    openvdb::GridPtrVec grids;
    openvdb::MetaMap::Ptr metadata = std::make_shared<openvdb::MetaMap>();
};

/// @brief Parse a complete `.vdb` file held in memory, behind the crash guard (see above).
/// @throw openvdb::IoError "empty file", "not a VDB file", "no grids (truncated?)", "corrupt VDB
///        data (the OpenVDB reader crashed on it: ...)", or OpenVDB's own parse error, prefixed by
///        nothing: callers add the file name
VdbFile parseVdb(const std::string& bytes);

/// @brief Read and parse the file at @a path.
/// @throw openvdb::IoError if it cannot be opened or read, or as parseVdb
VdbFile readVdbFile(const std::string& path);

/// @brief Read @a in to its end and parse it (standard input, a pipe).
VdbFile readVdbStream(std::istream& in);

/// Serialise @a file to the bytes of a `.vdb` file.
std::string serializeVdb(const VdbFile& file);

/// @brief Write @a bytes to @a path atomically: temporary file in the same folder, fsync, rename.
/// @throw openvdb::IoError on any failure; the destination is then untouched and no temporary
///        file remains
void writeFileAtomic(const std::string& path, const std::string& bytes);

/// @brief Write @a file to @a path atomically (see writeFileAtomic).
void writeVdbFile(const VdbFile& file, const std::string& path);

} // namespace vdbrad
