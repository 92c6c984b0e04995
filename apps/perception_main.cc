// moslam-perception: the perception commands of moslam (render, detect, perceive, and simulate
// with --perception rendered). Users run them as `moslam <command>`, which starts this
// executable (cli.h); it links PCL, VTK and OpenCV so that `moslam` itself does not.
#include "cli.h"
#include "commands.h"

int main(int argc, char** argv) {
  namespace cli = moslam::cli;
  CLI::App app{"moslam-perception: the perception commands of moslam (run them as `moslam "
               "<command>`)"};
  cli::Commands commands(app);
  commands.add(cli::RegisterSimulate(app, cli::MakeRenderedPerception));
  commands.add(cli::RegisterRender(app));
  commands.add(cli::RegisterDetect(app));
  commands.add(cli::RegisterPerceive(app));
  return commands.run(argc, argv);
}
