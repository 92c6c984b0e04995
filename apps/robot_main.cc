// moslam-robot: the robot-process commands of moslam (robot, team), over Cyclone DDS. Users run
// them as `moslam <command>`, which starts this executable (cli.h); it links Cyclone DDS so that
// `moslam` itself does not.
#include "cli.h"
#include "commands.h"

int main(int argc, char** argv) {
  namespace cli = moslam::cli;
  CLI::App app{"moslam-robot: the robot-process commands of moslam (run them as `moslam "
               "<command>`)"};
  cli::TuneProcessForSolving();
  cli::Commands commands(app);
  commands.add(cli::RegisterRobot(app));
  commands.add(cli::RegisterTeam(app));
  return commands.run(argc, argv);
}
