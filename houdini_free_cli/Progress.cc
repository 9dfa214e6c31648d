#include "Progress.h"

#include <atomic>
#include <csignal>
#include <cstdio>
#include <mutex>
#include <unistd.h>

namespace vdbrad {
namespace cli {

namespace {

std::atomic<int> gSignal{0};
std::mutex gDrawMutex;

extern "C" void
onSignal(int sig)
{
    if (gSignal.exchange(sig) != 0) {
        // Second signal: the user really wants out now.
        std::signal(sig, SIG_DFL);
        std::raise(sig);
    }
}

} // namespace

ProgressInterrupter::ProgressInterrupter(bool quiet)
    : mQuiet(quiet)
    , mTerminal(::isatty(STDERR_FILENO) == 1)
{
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
}

ProgressInterrupter::~ProgressInterrupter()
{
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
}

bool ProgressInterrupter::signalled() { return gSignal.load() != 0; }
int ProgressInterrupter::signalNumber() { return gSignal.load(); }

void
ProgressInterrupter::start(const char* name)
{
    std::lock_guard<std::mutex> lock(gDrawMutex);
    mName = name ? name : "working";
    mLastPercent = -1;
    mStart = mLastDraw = std::chrono::steady_clock::now();
    if (mQuiet || !mTerminal) return;
    std::fprintf(stderr, "\r\033[K%s...", mName.c_str());
    std::fflush(stderr);
}

void
ProgressInterrupter::end()
{
    end("done");
}

void
ProgressInterrupter::end(const std::string& result)
{
    std::lock_guard<std::mutex> lock(gDrawMutex);
    if (mQuiet) return;
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - mStart).count();
    std::fprintf(stderr, "%s%s: %s in %.2f s\n", mTerminal ? "\r\033[K" : "", mName.c_str(),
        result.c_str(), s);
    std::fflush(stderr);
}

bool
ProgressInterrupter::wasInterrupted(int percent)
{
    if (percent >= 0 && !mQuiet) draw(percent);
    return signalled();
}

void
ProgressInterrupter::draw(int percent)
{
    // Called from worker threads: serialise, and redraw at most ~10 times a second on a terminal,
    // nothing in a log.
    std::lock_guard<std::mutex> lock(gDrawMutex);
    const auto now = std::chrono::steady_clock::now();
    // Logs get one line per step (end()); only a terminal gets the live bar.
    if (!mTerminal) return;
    if (percent == mLastPercent || now - mLastDraw < std::chrono::milliseconds(100)) return;
    const int width = 30, filled = percent * width / 100;
    std::fprintf(stderr, "\r%s [%s%s] %3d%%", mName.c_str(), std::string(filled, '#').c_str(),
        std::string(width - filled, ' ').c_str(), percent);
    std::fflush(stderr);
    mLastPercent = percent;
    mLastDraw = now;
}

} // namespace cli
} // namespace vdbrad
