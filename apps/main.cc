// moslam: multi-robot object-based SLAM tools.
#include <fmt/core.h>

#include <exception>
#include <map>

#include "commands.h"
#include "moslam/common/errors.h"

int main(int argc, char** argv) {
  CLI::App app{"moslam: multi-robot object-based SLAM (pose graphs on SE(3), distributed Gauss-Seidel)"};
  app.require_subcommand(1);
  std::map<const CLI::App*, moslam::cli::Runner> runners;
  auto add = [&](const moslam::cli::Runner& r) {
    runners[app.get_subcommands([](const CLI::App*) { return true; }).back()] = r;
  };
  add(moslam::cli::RegisterSolve(app));
  add(moslam::cli::RegisterDgs(app));
  add(moslam::cli::RegisterRobot(app));
  add(moslam::cli::RegisterTeam(app));
  add(moslam::cli::RegisterSimulate(app));
  add(moslam::cli::RegisterRender(app));
  add(moslam::cli::RegisterDetect(app));
  add(moslam::cli::RegisterPerceive(app));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    for (const CLI::App* sub : app.get_subcommands()) return runners.at(sub)();
  } catch (const moslam::Error& e) {
    fmt::print(stderr, "moslam: error: {}\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    fmt::print(stderr, "moslam: internal error: {}\n", e.what());
    return 1;
  }
  return 1;
}
