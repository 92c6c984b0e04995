// moslam: multi-robot object-based SLAM tools. This executable holds the pose-graph commands and
// loads only what they need; the others run in the executables beside it (cli.h).
#include "cli.h"
#include "commands.h"

int main(int argc, char** argv) {
  namespace cli = moslam::cli;
  CLI::App app{"moslam: multi-robot object-based SLAM (pose graphs on SE(3), distributed Gauss-Seidel)"};
  cli::TuneProcessForSolving();
  cli::Commands commands(app);
  commands.add(cli::RegisterSolve(app));
  commands.add(cli::RegisterDgs(app));
  commands.add(cli::RegisterSpoil(app));
  // simulate with sampled sensing runs here; --perception rendered hands the command over.
  commands.add(cli::RegisterSimulate(
      app, [argv](const cli::RenderedPerceptionArgs&) -> moslam::ExperimentConfig::Perceive {
        cli::ExecSibling(cli::kPerceptionExecutable, argv);
      }));
  const auto forward = [&](const char* name, const char* description, const char* executable) {
    commands.add(cli::AddForwardedCommand(app, name, description, executable, argv));
  };
  forward("robot", cli::kRobotDescription, cli::kRobotExecutable);
  forward("team", cli::kTeamDescription, cli::kRobotExecutable);
  forward("render", cli::kRenderDescription, cli::kPerceptionExecutable);
  forward("detect", cli::kDetectDescription, cli::kPerceptionExecutable);
  forward("perceive", cli::kPerceiveDescription, cli::kPerceptionExecutable);
  return commands.run(argc, argv);
}
