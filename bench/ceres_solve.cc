// ceres_solve: a g2o pose graph solved by Ceres as a whole process, for the whole-process
// comparison of scripts/bench-solve.sh. The file's vertices are the initial estimate (the script
// writes moslam's chordal estimate with `moslam solve FILE --max-iterations 0 --out`, so Ceres
// starts where moslam's solver starts, without paying for the initialisation); the stopping rule
// is moslam's default (a step that changes the cost by less than 1e-10 relative); Ceres'
// Levenberg-Marquardt on SPARSE_NORMAL_CHOLESKY (SuiteSparse), one thread. Ceres and its CHOLMOD
// are the Debian packages as they are: this links nothing of moslam's solver.
//
//   ceres_solve INITIAL.g2o [--drop-indefinite-coupling] [--rel-tol X]
//
// Prints one JSON line: initial_cost, final_cost (moslam's PoseGraph::cost of Ceres' estimate),
// iterations, termination.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "ceres_pose_graph.h"
#include "moslam/io/g2o.h"

int main(int argc, char** argv) {
  CLI::App app{"ceres_solve: a g2o pose graph solved by Ceres (whole-process benchmark)"};
  std::string input;
  double relative_tolerance = 1e-10;
  moslam::G2oReadOptions read;
  app.add_option("input", input, "g2o file with a vertex (initial estimate) per variable")
      ->required();
  app.add_flag("--drop-indefinite-coupling", read.drop_indefinite_coupling);
  app.add_option("--rel-tol", relative_tolerance, "Ceres function_tolerance")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    const moslam::Dataset data = moslam::ReadG2o(input, read);
    const moslam::Key anchor = moslam::GaugeAnchor(data.graph);
    const moslam_bench::CeresRun run =
        moslam_bench::SolveWithCeres(data.graph, data.initial, anchor, 1, relative_tolerance);
    const ceres::Solver::Summary& s = run.summary;
    std::cout << nlohmann::json{{"input", input},
                                {"initial_cost", s.initial_cost},
                                {"final_cost", data.graph.cost(run.values)},
                                {"iterations", s.num_successful_steps + s.num_unsuccessful_steps},
                                {"termination", ceres::TerminationTypeToString(s.termination_type)}}
                     .dump()
              << "\n";
  } catch (const std::exception& e) {
    std::cerr << "ceres_solve: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
