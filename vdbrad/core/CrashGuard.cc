// CrashGuard: the checking child, its limits, and how its end is reported (see CrashGuard.h).
#include "vdbrad/core/CrashGuard.h"
#include "vdbrad/core/ProcessInfo.h"

#include "vdbrad/core/Errors.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <poll.h>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace vdbrad {

namespace {

// Corrupt sizes make OpenVDB allocate gigabytes (a "string" of 4 GiB, zero-filled, page by page)
// before failing. The child may grow its address space by 256 MiB plus 1024 times the file size,
// far beyond what a valid file expands to (a constant leaf compresses some 100 times), so such
// files fail at once with std::bad_alloc.
void
limitChildAddressSpace(size_t fileSize)
{
    const double now = virtualBytes();
    if (now <= 0.0) return;
    const double limit = now + double(256 << 20) + 1024.0 * double(fileSize);
    struct rlimit rl;
    if (::getrlimit(RLIMIT_AS, &rl) != 0 || limit >= double(rl.rlim_cur)) return;
    rl.rlim_cur = rlim_t(limit);
    ::setrlimit(RLIMIT_AS, &rl);
}

// A corrupt count makes OpenVDB loop billions of times over the end of the data (RootNode's
// tile loop does not check the stream). A valid file parses at well under 1 s per MB: the child
// gets 5 s of CPU plus 5 s per MB, then SIGXCPU.
unsigned
childCpuSeconds(size_t fileSize)
{
    return 5 + unsigned(5 * (fileSize >> 20));
}

void
limitChildCpu(size_t fileSize)
{
    const rlim_t seconds = childCpuSeconds(fileSize);
    struct rlimit rl;
    if (::getrlimit(RLIMIT_CPU, &rl) != 0) return;
    if (rl.rlim_cur == RLIM_INFINITY || seconds < rl.rlim_cur) {
        rl.rlim_cur = seconds;
        ::setrlimit(RLIMIT_CPU, &rl);
    }
}

// A child that sleeps or deadlocks (a lock inherited mid-operation across fork(), a reader that
// waits forever) spends no CPU time, so the CPU limit never fires: the parent also gives up after
// three times the CPU allowance of wall-clock time plus 15 s (30 s for a small file), enough for a
// loaded machine.
unsigned
childWallSeconds(size_t fileSize)
{
    return 3 * childCpuSeconds(fileSize) + 15;
}

// Exit codes of the checking child (below 128, and unlike a sanitizer's or libFuzzer's).
constexpr int kChildDone = 0, kChildThrew = 42;

// Reads the child's message until it closes the pipe (it exits) or @a deadline passes.
// Returns false on the deadline.
bool
readUntilClosed(int fd, std::string& message, std::chrono::steady_clock::time_point deadline)
{
    char chunk[512];
    for (;;) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
            deadline - std::chrono::steady_clock::now()).count();
        if (left <= 0) return false;
        struct pollfd p = {fd, POLLIN, 0};
        const int ready = ::poll(&p, 1, int(std::min<long long>(left, 1 << 30)));
        if (ready < 0 && errno == EINTR) continue;
        if (ready == 0) return false;
        if (ready < 0) return true;   // cannot wait on it: waitpid below still tells the outcome
        const ssize_t n = ::read(fd, chunk, sizeof(chunk));
        if (n > 0) message.append(chunk, size_t(n));
        else if (n < 0 && errno == EINTR) continue;
        else return true;
    }
}

} // namespace

bool
runGuarded(const std::function<void()>& work, size_t inputBytes, unsigned wallSeconds)
{
    if (wallSeconds == 0) wallSeconds = childWallSeconds(inputBytes);
    // A second try for a child that hung: fork() copies only the calling thread, so a lock that
    // another thread (a TBB worker, the allocator) held at that instant stays locked in the
    // child for ever. That is a race, not a property of the input (seen once in a sanitized
    // test run that forks after TBB work); a reader that really hangs on the input hangs twice.
    for (int attempt = 1;; ++attempt) {
        int fds[2];
        if (::pipe(fds) != 0) return false;
        const pid_t pid = ::fork();
        if (pid < 0) {
            ::close(fds[0]);
            ::close(fds[1]);
            return false;
        }
        if (pid == 0) {
            // The child has only this thread: TBB must not wait for the parent's workers (Tree's
            // destructor uses parallel_for), so everything runs in an arena of one. _exit skips
            // atexit handlers and stdio buffers that belong to the parent.
            ::close(fds[0]);
            // OpenVDB's warnings and glibc's abort messages would repeat or precede the parent's
            // one line: the child is silent.
            const int null = ::open("/dev/null", O_WRONLY);
            if (null >= 0) {
                ::dup2(null, STDOUT_FILENO);
                ::dup2(null, STDERR_FILENO);
                ::close(null);
            }
            limitChildAddressSpace(inputBytes);
            limitChildCpu(inputBytes);
            // The application's crash handlers (or a fuzzer's) are not for this child: a crash must
            // reach the parent as the signal it is.
            for (int sig : {SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL, SIGXCPU}) {
                std::signal(sig, SIG_DFL);
            }
            int code = kChildDone;
            std::string message;
            try {
                tbb::task_arena serial(1);
                serial.execute(work);
            } catch (const std::exception& e) {
                code = kChildThrew;
                message = errorMessage(e);
            } catch (...) {
                code = kChildThrew;
                message = "corrupt VDB data";
            }
            for (size_t done = 0; done < message.size();) {
                const ssize_t n = ::write(fds[1], message.data() + done, message.size() - done);
                if (n <= 0) break;
                done += size_t(n);
            }
            ::_exit(code);
        }
        ::close(fds[1]);
        // Read the message before waiting so a long one cannot block the child.
        std::string message;
        const bool finished = readUntilClosed(fds[0], message,
            std::chrono::steady_clock::now() + std::chrono::seconds(wallSeconds));
        ::close(fds[0]);
        if (!finished) ::kill(pid, SIGKILL);
        int status = 0;
        pid_t r = -1;
        do {
            r = ::waitpid(pid, &status, 0);
        } while (r < 0 && errno == EINTR);
        // ECHILD: the application reaps children itself (SIGCHLD ignored); parse unguarded.
        if (r != pid) return false;
        if (!finished && attempt < 2) continue;
        if (!finished) {
            OPENVDB_THROW(openvdb::IoError, "corrupt VDB data (the OpenVDB reader did not finish "
                "within " << wallSeconds << " s, twice; it may have deadlocked)");
        }
        if (WIFEXITED(status) && WEXITSTATUS(status) == kChildDone) return true;
        if (WIFEXITED(status) && WEXITSTATUS(status) == kChildThrew) {
            OPENVDB_THROW(openvdb::IoError, message);
        }
        if (WIFSIGNALED(status) && WTERMSIG(status) == SIGXCPU) {
            OPENVDB_THROW(openvdb::IoError, "corrupt VDB data (the OpenVDB reader did not finish "
                "within " << childCpuSeconds(inputBytes) << " s of CPU time)");
        }
        if (WIFSIGNALED(status)) {
            const char* name = ::strsignal(WTERMSIG(status));
            OPENVDB_THROW(openvdb::IoError, "corrupt VDB data (the OpenVDB reader crashed on it: "
                << (name ? name : "signal " + std::to_string(WTERMSIG(status))) << ")");
        }
        // A sanitizer or fuzzer runtime reports a crash by exiting with its own code.
        OPENVDB_THROW(openvdb::IoError, "corrupt VDB data (the OpenVDB reader failed on it: exit "
            "status " << WEXITSTATUS(status) << ")");
    }
}

} // namespace vdbrad
