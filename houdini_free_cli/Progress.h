// Progress: the interrupter the tool hands to the library (util::NullInterrupter interface).
//
// It draws a bar on stderr when stderr is a terminal and one line per finished step otherwise
// (farm logs), stays silent with --quiet, and turns SIGINT/SIGTERM into cancellation: the first
// signal makes wasInterrupted() true so the library unwinds and the tool leaves no output; a
// second one kills the process the default way.
#pragma once

#include <openvdb/util/NullInterrupter.h>

#include <chrono>
#include <string>

namespace vdbrad {
namespace cli {

class ProgressInterrupter : public openvdb::util::NullInterrupter
{
public:
    explicit ProgressInterrupter(bool quiet);
    ~ProgressInterrupter() override;

    void start(const char* name = nullptr) override;
    void end() override;
    /// End the current step with a short result ("residual 1e-5") on the same line.
    void end(const std::string& result);
    bool wasInterrupted(int percent = -1) override;

    /// True once SIGINT or SIGTERM has arrived.
    static bool signalled();
    /// The signal that arrived (0 if none).
    static int signalNumber();

private:
    void draw(int percent);
    bool mQuiet, mTerminal;
    std::string mName;
    int mLastPercent = -1;
    std::chrono::steady_clock::time_point mStart, mLastDraw;
};

} // namespace cli
} // namespace vdbrad
