// Errors: vdbrad reports problems with OpenVDB's exception types (ValueError for bad values,
// TypeError for wrong grid types, IoError for files, KeyError for missing grids) so that plugin
// code already catching openvdb::Exception keeps working; Cancelled is the one type of its own.
#pragma once

#include <openvdb/Exceptions.h>

#include <cstring>
#include <string>

namespace vdbrad {

/// Thrown when an interrupter asks a long operation to stop.
class Cancelled : public openvdb::Exception
{
public:
    Cancelled() noexcept : openvdb::Exception("Cancelled") {}
    explicit Cancelled(const std::string& msg) noexcept : openvdb::Exception("Cancelled", &msg) {}
};

/// The message of @a e without OpenVDB's "TypeName: " prefix, for one-line user reports.
/// A checkpoint file that cannot be read, written or resumed (FixedPointIteration.h); its
/// message names the file.
class CheckpointError : public openvdb::IoError
{
public:
    explicit CheckpointError(const std::string& msg) noexcept : openvdb::IoError(msg) {}
};

inline std::string
errorMessage(const std::exception& e)
{
    const char* what = e.what();
    if (!what) return "unknown error";
    if (dynamic_cast<const openvdb::Exception*>(&e)) {
        if (const char* colon = std::strstr(what, ": ")) return std::string(colon + 2);
    }
    return what;
}

} // namespace vdbrad
