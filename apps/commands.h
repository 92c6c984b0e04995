// Subcommands of the `moslam` tool. Each registers its options on the app and runs when chosen;
// a run returns the process exit code (0 success, 1 bad input or failed solve).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>

namespace moslam::cli {

using Runner = std::function<int()>;

// `moslam solve <file.g2o | folder>`: centralized Gauss-Newton / LM.
Runner RegisterSolve(CLI::App& app);

}  // namespace moslam::cli
