// `moslam spoil <folder | file> --fraction P --seed S --out DIR`: a multi-robot pose graph with
// wrong inter-robot loop closures added (robust/spoil.h), written in the distributed-mapper
// layout (0.g2o .. N-1.g2o) with the list of the added factors (outliers.txt: one line
// "<key a> <key b>" each, in the keys' printed form).
#include <fmt/core.h>

#include <filesystem>
#include <fstream>

#include "commands.h"
#include "moslam/common/errors.h"
#include "moslam/io/g2o.h"
#include "moslam/robust/spoil.h"

namespace moslam::cli {
namespace {

struct SpoilArgs {
  std::string input, out;
  double fraction = 0.5;
  std::uint32_t seed = 1;
  G2oReadOptions read;
};

int RunSpoil(const SpoilArgs& a) {
  const Dataset data = ReadG2o(a.input, a.read);
  SpoilOptions options;
  options.fraction = a.fraction;
  options.seed = a.seed;
  options.planar = data.planar;
  const SpoiledGraph spoiled = SpoilSeparators(data.graph, options);
  G2oWriteOptions w;
  w.scheme = a.read.scheme;
  w.planar = data.planar;
  WriteG2oFolder(a.out, spoiled.graph, data.initial, w);
  const std::string list = (std::filesystem::path(a.out) / "outliers.txt").string();
  std::ofstream file(list);
  for (std::size_t i = 0; i < spoiled.outlier.size(); ++i) {
    if (!spoiled.outlier[i]) continue;
    const RelativePoseFactor& f = spoiled.graph.factors()[i];
    file << ToString(f.a()) << ' ' << ToString(f.b()) << '\n';
  }
  file.close();
  if (!file) throw Error("spoil: could not write " + list);
  fmt::print("{}: {} {}, {} wrong ones added ({:.1f} % of {}); written to {}\n", a.input,
             spoiled.separators, spoiled.single_robot ? "loop closures" : "separators",
             spoiled.added, 100.0 * spoiled.added / std::max(1, spoiled.added + spoiled.separators),
             spoiled.added + spoiled.separators, a.out);
  return 0;
}

}  // namespace

Runner RegisterSpoil(CLI::App& app) {
  auto args = std::make_shared<SpoilArgs>();
  CLI::App* sub = app.add_subcommand(
      "spoil",
      "Add wrong loop closures (outlier experiments): between robots to a multi-robot pose "
      "graph, between poses that are not consecutive to a single-robot one");
  sub->add_option("input", args->input, "g2o file or distributed-mapper folder")->required();
  sub->add_option("--fraction", args->fraction,
                  "fraction of the separators (one robot: loop closures) of the result that "
                  "are wrong, in [0, 1)")
      ->check(InRange(0.0, 0.999))
      ->capture_default_str();
  sub->add_option("--seed", args->seed, "random seed")->capture_default_str();
  sub->add_option("--out", args->out, "output folder (0.g2o .. N-1.g2o, outliers.txt)")
      ->required();
  AddG2oReadFlags(sub, &args->read);
  return [args] { return RunSpoil(*args); };
}

}  // namespace moslam::cli
