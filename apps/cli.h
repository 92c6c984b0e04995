// What both executables of the `moslam` command share: running the chosen subcommand with the
// error conventions of the CLI, and handing a command over to the perception executable.
//
// The command is split by what the commands link, so that each loads only what it uses (start-up
// is dominated by the dynamic loader: every shared library costs milliseconds):
//   moslam             solve, dgs, simulate (sampled sensing): Eigen, CHOLMOD
//   moslam-robot       robot, team: + Cyclone DDS
//   moslam-perception  render, detect, perceive, simulate --perception rendered: + PCL, VTK,
//                      OpenCV
// The user types `moslam <command>` for all of them: `moslam` replaces itself (execv, same
// arguments) with the executable of the command. They live in one folder (the build's apps/, or
// wherever they are installed together).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace moslam::cli {

using Runner = std::function<int()>;

// The subcommands of one executable and what runs them.
class Commands {
 public:
  // `app` requires exactly one subcommand, or --version (prints "moslam <version>", exit 0).
  explicit Commands(CLI::App& app);
  // `run` runs the subcommand added to the app last.
  void add(Runner run);
  // Parses argv and runs the chosen subcommand. Exit codes: 0 success, 1 bad input or a failed
  // run (printed as "moslam: error: <reason>"), CLI11's for a parse error or --help.
  int run(int argc, char** argv);

 private:
  CLI::App& app_;
  std::vector<std::pair<CLI::App*, Runner>> runners_;
};

// Process-wide settings of the pose-graph executables, measured on smallGrid3D (README, the solve
// table):
// - freed memory stays mapped for reuse (glibc malloc: no mmap for blocks under 64 MB, no trim
//   under 256 MB): the solvers free and re-allocate their factorization workspaces at every
//   iteration, and with glibc's defaults each re-allocation maps fresh pages; page faults are a
//   fifth of a small solve on this machine kind (1,000 faults, 700 with this);
// - OpenBLAS (when it is the BLAS linked, cmake/FindCHOLMOD.cmake) computes on the calling
//   thread: its worker threads cost 330 context switches per small solve and gain nothing on
//   two shared cores.
void TuneProcessForSolving();

// The committed detector (models/detector of the source tree): the model and its class names,
// the defaults of `simulate --perception rendered`, `perceive` and `detect`.
std::string CommittedDetectorModel();
std::string CommittedDetectorClasses();

// The executables beside `moslam`.
inline constexpr const char* kRobotExecutable = "moslam-robot";
inline constexpr const char* kPerceptionExecutable = "moslam-perception";

// Option checks whose errors say what the option needs ("--robots: must be a positive number, not
// 0"); CLI11's PositiveNumber and NonNegativeNumber print their range as "0.000000 to 1797...".
CLI::Validator Positive();
CLI::Validator NonNegative();
// A real number in [lo, hi] ("--fraction: must be a number in [0, 0.999], not 1.5"); CLI11's Range
// prints doubles as "0.000000 to 0.999000". Integer options keep CLI::Range.
CLI::Validator InRange(double lo, double hi);

// Checked before the work whose result the file `path` (given as `option`) would hold: throws
// InvalidInputError when it is a folder or its folder does not exist, which would fail the write
// only at the end.
void CheckOutputFile(const std::string& path, const std::string& option);

// A cost against the centralized optimum's, as `cost / central`, or none when the optimum's is at
// rounding level: below 1e-20 (residuals below 1e-10), what double rounding leaves of measurements
// that fit exactly (7e-30 for a ten-pose chain), a ratio to which says nothing.
inline std::optional<double> CostRatio(double cost, double central) {
  if (!(central >= 1e-20)) return std::nullopt;
  return cost / central;
}

// Replaces the process with `executable` found beside the running one, with the same arguments.
// Returns only on failure, by throwing moslam::Error naming the path it tried and the likely
// cause.
[[noreturn]] void ExecSibling(const char* executable, char** argv);

// A subcommand of `moslam` that only forwards its whole command line (its --help included) to
// `executable`; its options are that executable's. Returns the runner that does it.
Runner AddForwardedCommand(CLI::App& app, const std::string& name, const std::string& description,
                           const char* executable, char** argv);

}  // namespace moslam::cli
