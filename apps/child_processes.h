// Child processes of a command (`moslam team` starts one `moslam robot` per robot): each runs this
// executable again with its own arguments, its stdout and stderr in a log file.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace moslam::cli {

// Starts this executable (/proc/self/exe) with `args` (args[0] its name), stdout and stderr
// appended to a fresh `log`. The argument vector is built before the fork: the child only calls
// async-signal-safe functions until it executes. Throws moslam::Error when fork fails.
pid_t SpawnSelf(const std::vector<std::string>& args, const std::filesystem::path& log);

// Waits for `children` (pid -> an id) to end, killing those still running at `timeout`; the exit
// code per id: the process's, 128 + the signal that ended it, or -1 when killed at the timeout.
std::map<int, int> WaitForChildren(const std::map<pid_t, int>& children,
                                   std::chrono::milliseconds timeout);

}  // namespace moslam::cli
