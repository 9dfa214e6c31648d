// CrashGuard: work on untrusted bytes runs first in a forked child, so that a reader that crashes,
// aborts, corrupts its heap, allocates without bound or never finishes costs the caller one
// IoError, not the process (GridIO.h says why OpenVDB's reader needs it).
//
// The child runs the work in a TBB arena of one thread (the parent's TBB workers do not exist
// there), silent, with default crash signal handlers, and with limits that turn corrupt sizes and
// counts into quick failures (address space +256 MiB + 1024 x the input size; 5 s + 5 s per MB of
// CPU; 3 x that + 15 s of wall-clock time, for a child that deadlocks without spending CPU). Where
// fork() or waitpid() are unavailable (no process left, SIGCHLD ignored by the application), no
// child runs and the caller does the work itself.
#pragma once

#include <cstddef>
#include <functional>

namespace vdbrad {

/// @brief Run @a work in a forked child with the reader's limits for an input of @a inputBytes
///        (see above) and report how it ended. parseVdb's work parses; tests give it work that
///        crashes, throws or hangs.
/// @param wallSeconds  give up (and kill the child) after this long; 0: the reader's default
/// @return true if @a work returned in the child, false if no child could be run or waited for
///         (the caller then does the work itself, unguarded)
/// @throw openvdb::IoError with the message of an exception @a work threw, or saying that the
///        child crashed (naming the signal), ran out of CPU time or did not finish in time
bool runGuarded(const std::function<void()>& work, size_t inputBytes, unsigned wallSeconds = 0);

} // namespace vdbrad
