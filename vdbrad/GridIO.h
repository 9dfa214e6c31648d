// GridIO: reading and writing whole `.vdb` files, from paths or streams, all-or-nothing.
//
// Reading: the bytes are read completely first, the header is checked, then OpenVDB parses them
// from memory with delayed loading off. So a pipe reads the same as a file, no
// /tmp/openvdb_temp_* copy is left behind, corrupt voxel data is found now rather than later,
// and a file truncated inside its header (which OpenVDB 10 reads as "0 grids") is an error.
// Crash guard: OpenVDB 10's reader trusts sizes and masks in the file, so some corrupt files
// crash it (segfaults, aborts, heap corruption; fixed in part in OpenVDB 11). vdbrad reads files
// from other tools, unattended, so the bytes are first parsed in a forked child, which reads
// every leaf buffer, frees everything and exits; the parent parses only if the child succeeded,
// and reports a child's crash or error as an IoError. The child runs OpenVDB in a TBB arena of
// one thread (the parent's TBB workers do not exist there), silent, with default crash signal
// handlers, and with limits that turn corrupt sizes and counts into quick failures (address space
// +256 MiB + 1024 x the file size; 5 s + 5 s per MB of CPU; 3 x that + 15 s of wall-clock time,
// for a child that deadlocks without spending CPU). Cost: a second parse plus the fork;
// measured on `vdbrad make cornell - --res 256` (4.2 MB, 410k surface voxels, 2-core CI VM):
// parseVdb 2.4 s instead of 1.2 s, i.e. +1.2 s, where solving that scene takes minutes. Where
// fork() or waitpid() are unavailable (no process left, SIGCHLD ignored by the application), the
// bytes are parsed unguarded.
// Writing: the file is serialised in memory, written to a temporary file in the destination's
// folder, flushed and renamed over the destination: a failure (full disk, cancel) leaves the
// destination as it was and no partial file. Standard output gets the same bytes in one go.
#pragma once

#include <openvdb/openvdb.h>

#include <functional>
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

/// @brief The crash guard itself: run @a work in a forked child with the reader's limits for an
///        input of @a inputBytes (see above) and report how it ended. parseVdb's work parses;
///        tests give it work that crashes, throws or hangs.
/// @param wallSeconds  give up (and kill the child) after this long; 0: the reader's default
/// @return true if @a work returned in the child, false if no child could be run or waited for
///         (the caller then does the work itself, unguarded)
/// @throw openvdb::IoError with the message of an exception @a work threw, or saying that the
///        child crashed (naming the signal), ran out of CPU time or did not finish in time
bool runGuarded(const std::function<void()>& work, size_t inputBytes, unsigned wallSeconds = 0);

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
