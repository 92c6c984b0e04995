#include "cli.h"

#include <fmt/core.h>
#include <malloc.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <functional>
#include <string>
#include <system_error>
#include <utility>

#include "moslam/common/errors.h"

// OpenBLAS's, when linked (weak: null with another BLAS).
extern "C" void openblas_set_num_threads(int) __attribute__((weak));

namespace moslam::cli {

namespace {

// A check that the option's text is a finite number `accept` takes; else `need`.
CLI::Validator NumberCheck(std::function<bool(double)> accept, std::string need,
                           const std::string& name) {
  return CLI::Validator(
      [accept = std::move(accept), need = std::move(need)](std::string& text) -> std::string {
        // Locale-independent and whole-token, as the g2o reader reads numbers.
        const char* first = text.data();
        const char* last = text.data() + text.size();
        if (first != last && *first == '+') ++first;
        double v = 0.0;
        const auto [end, ec] = std::from_chars(first, last, v);
        if (ec != std::errc() || end != last || !std::isfinite(v) || !accept(v)) {
          return std::string("must be ") + need + ", not " + text;
        }
        return {};
      },
      name, name);
}

}  // namespace

CLI::Validator Positive() {
  return NumberCheck([](double v) { return v > 0.0; }, "a positive number", "POSITIVE");
}

CLI::Validator NonNegative() {
  return NumberCheck([](double v) { return v >= 0.0; }, "a number >= 0", "NONNEGATIVE");
}

void CheckOutputFile(const std::string& path, const std::string& option) {
  const std::filesystem::path file(path), folder = file.parent_path();
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) {
    throw InvalidInputError(option + " '" + path + "' is a folder; give a file name");
  }
  if (!folder.empty() && !std::filesystem::is_directory(folder, ec)) {
    throw InvalidInputError(option + " '" + path + "': no folder '" + folder.string() +
                            "' to write it in");
  }
}

CLI::Validator InRange(double lo, double hi) {
  return NumberCheck([lo, hi](double v) { return v >= lo && v <= hi; },
                     fmt::format("a number in [{}, {}]", lo, hi), fmt::format("[{} - {}]", lo, hi));
}

Commands::Commands(CLI::App& app) : app_(app) {
  app_.require_subcommand(1);
  app_.set_version_flag("--version", std::string("moslam ") + MOSLAM_VERSION);
}

void Commands::add(Runner run) {
  runners_.emplace_back(app_.get_subcommands([](const CLI::App*) { return true; }).back(),
                        std::move(run));
}

int Commands::run(int argc, char** argv) {
  try {
    app_.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app_.exit(e);
  }
  try {
    for (const auto& [sub, run] : runners_) {
      if (sub->parsed()) return run();
    }
  } catch (const moslam::Error& e) {
    fmt::print(stderr, "moslam: error: {}\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    fmt::print(stderr, "moslam: internal error: {}\n", e.what());
    return 1;
  }
  return 1;
}

void TuneProcessForSolving() {
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
  if (openblas_set_num_threads != nullptr) openblas_set_num_threads(1);
}

void ExecSibling(const char* executable, char** argv) {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) {
    throw Error(std::string("cannot locate the running executable (/proc/self/exe: ") +
                ec.message() + ") to start " + executable + " beside it");
  }
  const std::string path = (self.parent_path() / executable).string();
  execv(path.c_str(), argv);  // argv[0] stays as typed: usage lines read `moslam <command>`
  const int error = errno;
  throw Error(fmt::format("this command runs in {}, which could not be started ({}): build or "
                          "install it beside {} (apps/cli.h)",
                          path, std::strerror(error), self.string()));
}

Runner AddForwardedCommand(CLI::App& app, const std::string& name, const std::string& description,
                           const char* executable, char** argv) {
  CLI::App* sub = app.add_subcommand(name, description);
  sub->prefix_command();  // every argument after the name belongs to the other executable
  sub->set_help_flag();   // --help too
  sub->allow_extras();
  return [executable, argv]() -> int { ExecSibling(executable, argv); };
}

std::string CommittedDetectorModel() {
  return std::string(MOSLAM_MODELS_DIR) + "/detector/moslam_yolo.onnx";
}

std::string CommittedDetectorClasses() {
  return std::string(MOSLAM_MODELS_DIR) + "/detector/classes.txt";
}

}  // namespace moslam::cli
