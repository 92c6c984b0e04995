// Runs the real `moslam` binary: bad input must exit non-zero with file and line, never crash;
// --json must end with one JSON object carrying the documented fields.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/whole_file.h"
#include "moslam/io/g2o.h"
#include "moslam/metrics/metrics.h"

namespace {

namespace fs = std::filesystem;

struct CommandResult {
  int exit_code;
  std::string out;  // stdout and stderr, interleaved
};

// Runs a shell command line, stderr into stdout.
CommandResult RunShell(const std::string& command_line) {
  const std::string cmd = command_line + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return {-1, "popen failed"};
  std::string out;
  std::array<char, 4096> buf;
  while (size_t n = fread(buf.data(), 1, buf.size(), pipe)) out.append(buf.data(), n);
  const int status = pclose(pipe);
  // A crash (signal) is reported as a distinct code so the tests can tell it from exit 1.
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out};
}

CommandResult RunMoslam(const std::string& args) {
  return RunShell(std::string(MOSLAM_BINARY) + " " + args);
}

std::string LastLine(const std::string& s) {
  std::istringstream in(s);
  std::string line, last;
  while (std::getline(in, line)) {
    if (!line.empty()) last = line;
  }
  return last;
}

class CliBadInput : public ::testing::TestWithParam<std::pair<const char*, std::string>> {};

const std::string kV = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n";
const std::string kI = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
std::string Edge(const std::string& ij, const std::string& info = kI) {
  return "EDGE_SE3:QUAT " + ij + " 1 0 0 0 0 0 1" + info;
}

TEST_P(CliBadInput, ExitsNonZeroNamingFileAndLine) {
  const auto& [name, text] = GetParam();
  const fs::path file = moslam::test::ScratchDir(name) / (std::string(name) + ".g2o");
  std::ofstream(file, std::ios::binary) << text;
  const CommandResult r = RunMoslam("solve " + file.string());
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("moslam: error: " + file.string()), std::string::npos) << r.out;
  if (std::string(name) != "empty") {
    EXPECT_NE(r.out.find(file.string() + ":3:"), std::string::npos) << r.out;
  }
  fs::remove(file);
}

INSTANTIATE_TEST_SUITE_P(
    Rejected, CliBadInput,
    ::testing::Values(
        std::make_pair("nan", kV + "EDGE_SE3:QUAT 0 1 nan 0 0 0 0 0 1" + kI),
        std::make_pair("inf", kV + "EDGE_SE3:QUAT 0 1 inf 0 0 0 0 0 1" + kI),
        std::make_pair("truncated", kV + "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0\n"),
        std::make_pair("non_number", kV + "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 abc" + kI),
        std::make_pair("non_spd", kV + Edge("0 1", " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 -1\n")),
        std::make_pair("unknown_tag", kV + "EDGE_FOO 0 1\n"),
        std::make_pair("dangling", kV + Edge("0 7")),
        std::make_pair("empty", std::string("# nothing here\n\n")),
        std::make_pair("binary", kV + std::string("\x7f\x45\x4c\x46\x02\x01\x00\xff\xfe\n", 10)),
        std::make_pair("out_of_range_id", kV + Edge("0 2594073385365405696"))),  // top byte '$'
    [](const auto& param_info) { return std::string(param_info.param.first); });

TEST(Cli, JsonLastLineHasTheDocumentedFields) {
  const CommandResult r = RunMoslam("solve " MOSLAM_DATASETS_DIR "/pgo/tinyGrid3D.g2o --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(LastLine(r.out));
  for (const char* key : {"initial_cost", "final_cost", "iterations", "seconds", "termination"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["termination"], "converged");
  EXPECT_LE(j["final_cost"].get<double>(), j["initial_cost"].get<double>());
}

TEST(Cli, FolderSolvesLikeItsFullGraph) {
  const std::string dir = MOSLAM_DATASETS_DIR
      "/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/blocks_world/"
      "9robots";
  const CommandResult folder = RunMoslam("solve " + dir + " --json");
  const CommandResult full = RunMoslam("solve " + dir + "/fullGraph.g2o --json");
  ASSERT_EQ(folder.exit_code, 0) << folder.out;
  ASSERT_EQ(full.exit_code, 0) << full.out;
  const auto a = nlohmann::json::parse(LastLine(folder.out));
  const auto b = nlohmann::json::parse(LastLine(full.out));
  EXPECT_EQ(a["factors"], b["factors"]);
  EXPECT_NEAR(a["initial_cost"].get<double>(), b["initial_cost"].get<double>(),
              1e-9 * b["initial_cost"].get<double>());
  EXPECT_NEAR(a["final_cost"].get<double>(), b["final_cost"].get<double>(),
              1e-9 * b["final_cost"].get<double>());
}

TEST(Cli, VersionNamesTheProjectsVersion) {
  const CommandResult version = RunMoslam("--version");
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_EQ(LastLine(version.out), std::string("moslam ") + MOSLAM_VERSION);
}

// Where an output folder cannot be made (a file in its way), the command says so as an input
// error, not as an internal one.
TEST(Cli, AnOutputFolderBlockedByAFileIsAnInputError) {
  const fs::path dir = moslam::test::ScratchDir("blocked_out");
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path file = dir / "a_file";
  std::ofstream(file) << "x";
  const CommandResult r = RunMoslam("solve " MOSLAM_DATASETS_DIR "/pgo/smallGrid3D.g2o --out " +
                                    (file / "result.g2o").string());
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("moslam: error: solve --out: cannot create '" + file.string() + "'"),
            std::string::npos)
      << r.out;
  fs::remove_all(dir);
}

TEST(Cli, UsageErrorsAndMissingFiles) {
  EXPECT_NE(RunMoslam("solve").exit_code, 0);
  EXPECT_NE(RunMoslam("solve x.g2o --method newton").exit_code, 0);
  const CommandResult missing = RunMoslam("solve /nonexistent/file.g2o");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.out.find("/nonexistent/file.g2o"), std::string::npos);
  // An edge-only file has nothing for --init file, but solves from odometry or chordal.
  const fs::path edges = moslam::test::ScratchDir("edges_only") / "edges_only.g2o";
  std::ofstream(edges) << Edge("0 1") << Edge("1 2") << Edge("2 0");
  const CommandResult no_vertices = RunMoslam("solve " + edges.string() + " --init file");
  EXPECT_EQ(no_vertices.exit_code, 1);
  EXPECT_NE(no_vertices.out.find("--init chordal"), std::string::npos) << no_vertices.out;
  EXPECT_EQ(RunMoslam("solve " + edges.string() + " --init odometry").exit_code, 0);
  fs::remove(edges);
}

TEST(Cli, ATwoDimensionalFileSolvesAndIsWrittenBackInTwoDimensions) {
  const fs::path out = moslam::test::ScratchDir("mit_solved") / "mit_solved.g2o";
  const CommandResult r =
      RunMoslam("solve " + std::string(MOSLAM_DATASETS_DIR) + "/pgo/MIT.g2o --out " + out.string());
  EXPECT_EQ(r.exit_code, 0) << r.out;
  std::ifstream in(out);
  std::string tag;
  in >> tag;
  EXPECT_EQ(tag, "VERTEX_SE2");
  fs::remove(out);
}

TEST(Cli, AFileOfVerticesAloneHasNothingToSolve) {
  const fs::path vertices = moslam::test::ScratchDir("vertices_only") / "vertices_only.g2o";
  std::ofstream(vertices) << kV;
  const CommandResult r = RunMoslam("solve " + vertices.string());
  fs::remove(vertices);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("the graph has no factors"), std::string::npos) << r.out;
}

TEST(CliDgs, AGraphItsMeasurementsFitExactlyReportsNoCostRatio) {
  const fs::path exact = moslam::test::ScratchDir("exact_fit") / "exact_fit.g2o";
  std::ofstream(exact) << kV << Edge("0 1");  // the edge is the vertices' relative pose
  const CommandResult text = RunMoslam("dgs " + exact.string() + " --robots 2 --refine");
  const CommandResult json = RunMoslam("dgs " + exact.string() + " --robots 2 --refine --json");
  fs::remove(exact);
  EXPECT_EQ(text.exit_code, 0) << text.out;
  EXPECT_NE(text.out.find("cost: two-stage 0, final 0, centralized GN 0\n"), std::string::npos)
      << text.out;
  EXPECT_EQ(text.out.find("nan"), std::string::npos) << text.out;
  ASSERT_EQ(json.exit_code, 0) << json.out;
  const nlohmann::json j = nlohmann::json::parse(LastLine(json.out));
  EXPECT_TRUE(j.at("final_cost_ratio").is_null()) << j.dump();
  EXPECT_EQ(j.at("final_cost").get<double>(), 0.0);
}

// Measurements that fit exactly but whose centralized optimum rounding leaves at 7e-30 (a ten-pose
// chain with loops): no ratio to it either (it printed 2.6e21 x centralized, and the robust line
// -1 relative).
TEST(CliDgs, ACentralizedCostAtRoundingLevelReportsNoRatio) {
  const fs::path file = moslam::test::ScratchDir("rounding_fit") / "loops.g2o";
  {
    std::ofstream out(file);
    for (int i = 0; i < 10; ++i) out << "VERTEX_SE2 " << i << " " << i << " 0 0\n";
    for (int i = 0; i < 9; ++i) out << "EDGE_SE2 " << i << " " << i + 1 << " 1 0 0 1 0 0 1 0 1\n";
    for (int i = 0; i < 6; ++i) out << "EDGE_SE2 " << i << " " << i + 3 << " 3 0 0 1 0 0 1 0 1\n";
  }
  const std::string dgs = "dgs " + file.string() + " --robots 3";
  const CommandResult text = RunMoslam(dgs + " --refine");
  ASSERT_EQ(text.exit_code, 0) << text.out;
  EXPECT_EQ(text.out.find("x centralized"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find(", centralized GN 7."), std::string::npos) << text.out;
  const CommandResult json = RunMoslam(dgs + " --json");
  ASSERT_EQ(json.exit_code, 0) << json.out;
  const nlohmann::json j = nlohmann::json::parse(LastLine(json.out));
  EXPECT_GT(j.at("centralized_cost").get<double>(), 0.0);
  EXPECT_TRUE(j.at("two_stage_cost_ratio").is_null()) << j.dump();
  EXPECT_TRUE(j.at("final_cost_ratio").is_null()) << j.dump();
  const CommandResult robust = RunMoslam(dgs + " --robust");
  ASSERT_EQ(robust.exit_code, 0) << robust.out;
  // The robots' refinement stops once F is at most its absolute tolerance (1e-20).
  const std::size_t line = robust.out.find("robots' GNC:");
  ASSERT_NE(line, std::string::npos) << robust.out;
  const std::string kept = "cost of the kept factors ";
  const std::size_t at = robust.out.find(kept, line);
  ASSERT_NE(at, std::string::npos) << robust.out;
  const std::string rest = robust.out.substr(at + kept.size());
  std::size_t number_end = 0;
  EXPECT_LE(std::stod(rest, &number_end), 1e-20) << robust.out;
  EXPECT_EQ(rest.compare(number_end, 38, " (the centralized's at rounding level)"), 0)
      << robust.out;
  fs::remove_all(file.parent_path());
}

TEST(Cli, ANumberOutOfRangeSaysWhatTheOptionNeeds) {
  const CommandResult zero = RunMoslam("simulate --robots 0");
  EXPECT_NE(zero.exit_code, 0);
  EXPECT_NE(zero.out.find("--robots: must be a positive number, not 0"), std::string::npos)
      << zero.out;
  const CommandResult negative = RunMoslam("solve x.g2o --max-iterations -1");
  EXPECT_NE(negative.exit_code, 0);
  EXPECT_NE(negative.out.find("--max-iterations: must be a number >= 0, not -1"),
            std::string::npos)
      << negative.out;
  const CommandResult text = RunMoslam("simulate --runs 2x");
  EXPECT_NE(text.exit_code, 0);
  EXPECT_NE(text.out.find("must be a positive number, not 2x"), std::string::npos) << text.out;
  const CommandResult fraction = RunMoslam("simulate --outliers 1.5");
  EXPECT_NE(fraction.exit_code, 0);
  EXPECT_NE(fraction.out.find("--outliers: must be a number in [0, 0.999], not 1.5"),
            std::string::npos)
      << fraction.out;
}

TEST(Cli, WritesG2oAndTumThatReadBack) {
  const fs::path dir = moslam::test::ScratchDir("out");
  fs::remove_all(dir);
  const CommandResult r = RunMoslam("solve " MOSLAM_DATASETS_DIR "/pgo/smallGrid3D.g2o --out " +
                          (dir / "out.g2o").string() + " --tum " + (dir / "tum").string() +
                          " --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_TRUE(fs::exists(dir / "tum" / "robot_0.tum"));
  // Solving the written optimum again: it is already converged, at the same cost.
  const CommandResult again = RunMoslam("solve " + (dir / "out.g2o").string() + " --init file --json");
  ASSERT_EQ(again.exit_code, 0) << again.out;
  const auto a = nlohmann::json::parse(LastLine(r.out));
  const auto b = nlohmann::json::parse(LastLine(again.out));
  EXPECT_NEAR(b["initial_cost"].get<double>(), a["final_cost"].get<double>(),
              1e-9 * a["final_cost"].get<double>());
  fs::remove_all(dir);
}

// ---- moslam dgs ----------------------------------------------------------------------------

const std::string kBlocksWorld = MOSLAM_DATASETS_DIR
    "/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/blocks_world/";

TEST(CliDgs, JsonLastLineHasTheDocumentedFields) {
  const CommandResult r = RunMoslam("dgs " + kBlocksWorld + "4robots --refine --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(LastLine(r.out));
  for (const char* key :
       {"final_cost", "two_stage_cost", "centralized_cost", "iterations_rotation",
        "iterations_pose", "iterations_refine", "iterations_total", "ate_poses", "are_poses_deg",
        "messages", "bytes", "termination_rotation", "termination_pose", "termination_refine",
        "refine_steps", "seconds_per_iteration"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_FALSE(j.contains("ate_objects"));  // no objects in blocks_world
  EXPECT_EQ(j["robots"], 4);
  EXPECT_EQ(j["termination_rotation"], "converged");
  EXPECT_EQ(j["termination_pose"], "converged");
  EXPECT_EQ(j["termination_refine"], "converged");
  EXPECT_EQ(j["iterations_total"].get<int>(), j["iterations_rotation"].get<int>() +
                                                  j["iterations_pose"].get<int>() +
                                                  j["iterations_refine"].get<int>());
  const double central = j["centralized_cost"].get<double>();
  EXPECT_LE(std::abs(j["final_cost"].get<double>() - central), 1e-4 * central);
  EXPECT_GT(j["two_stage_cost"].get<double>(), 1.01 * central);
  EXPECT_LE(j["ate_poses"].get<double>(), 1e-3);
  EXPECT_GT(j["bytes"].get<long long>(), j["messages"].get<long long>() * 16);
  // Without --refine: the two-stage estimate is final.
  const CommandResult plain = RunMoslam("dgs " + kBlocksWorld + "4robots --json");
  ASSERT_EQ(plain.exit_code, 0) << plain.out;
  const auto p = nlohmann::json::parse(LastLine(plain.out));
  EXPECT_EQ(p["final_cost"], p["two_stage_cost"]);
  EXPECT_EQ(p["iterations_refine"], 0);
  EXPECT_EQ(p["termination_refine"], "not run");
}

TEST(CliDgs, SplitsASingleRobotFileIntoRobots) {
  const CommandResult r = RunMoslam("dgs " MOSLAM_DATASETS_DIR
                                    "/pgo/smallGrid3D.g2o --robots 5 --order jacobi --refine "
                                    "--json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(LastLine(r.out));
  EXPECT_EQ(j["robots"], 5);
  EXPECT_EQ(j["order"], "jacobi");
  const double central = j["centralized_cost"].get<double>();
  EXPECT_LE(std::abs(j["final_cost"].get<double>() - central), 1e-4 * central);
}

TEST(CliDgs, PrintsOneLinePerSweepWithoutJson) {
  const CommandResult r = RunMoslam("dgs " + kBlocksWorld + "2robots --refine");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("rotation iteration     1  max change"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("pose     iteration     1  max change"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("refine   iteration     1  max change"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("refine   step   1:"), std::string::npos) << r.out;
  // The pose stage by conjugate gradients (--refine's) prints their residual too.
  EXPECT_TRUE(std::regex_search(r.out, std::regex("\npose     iteration +[0-9]+  max change "
                                                  "[^\n]*  cg residual [0-9.e+-]+\n")))
      << r.out;
  EXPECT_NE(r.out.find("bytes "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("cost: two-stage"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find('{'), std::string::npos);  // no JSON
}

// A refinement stopped short says so and what to try; one that converged prints no hint. MIT in 2
// robots without halving: its first Gauss-Newton step is rejected, and it converges in 12 steps
// (measured); with halving (the default) no step is rejected.
TEST(CliDgs, ARefinementStoppedAtItsStepLimitAfterRejectedStepsSaysWhatToTry) {
  const std::string halved = "dgs " MOSLAM_DATASETS_DIR "/pgo/MIT.g2o --robots 2 --refine";
  const CommandResult by_default = RunMoslam(halved);
  ASSERT_EQ(by_default.exit_code, 0) << by_default.out;
  EXPECT_NE(by_default.out.find("refine: converged after 10 step(s) (0 rejected, 1 halving(s))"),
            std::string::npos)
      << by_default.out;
  const std::string mit = halved + " --refine-backtracks 0";
  const CommandResult cut = RunMoslam(mit + " --refine-max-iter 2");
  ASSERT_EQ(cut.exit_code, 0) << cut.out;
  EXPECT_NE(cut.out.find("refine: max iterations after 2 step(s) (1 rejected, 0 halving(s))"),
            std::string::npos)
      << cut.out;
  EXPECT_NE(cut.out.find("with 1 of 2 steps rejected"), std::string::npos) << cut.out;
  EXPECT_NE(cut.out.find("--refine-linear-tol 1e-3"), std::string::npos) << cut.out;
  const CommandResult full = RunMoslam(mit);
  ASSERT_EQ(full.exit_code, 0) << full.out;
  EXPECT_NE(full.out.find("refine: converged"), std::string::npos) << full.out;
  EXPECT_EQ(full.out.find("--refine-linear-tol"), std::string::npos) << full.out;
}

// When half or more of the linear solves stop at the sweep cap with one rigid motion per robot,
// `dgs` names the coarse space of pieces; with pieces it has nothing to add. MIT in 4 robots with
// 6 sweeps per step (measured: every step at the cap, with pieces too).
TEST(CliDgs, LinearSolvesAtTheSweepCapNameTheCoarseSpaceOfPieces) {
  const std::string mit = "dgs " MOSLAM_DATASETS_DIR
                          "/pgo/MIT.g2o --robots 4 --refine --refine-max-sweeps 6 "
                          "--refine-max-iter 3";
  const CommandResult robots = RunMoslam(mit);
  ASSERT_EQ(robots.exit_code, 0) << robots.out;
  EXPECT_NE(robots.out.find("of 3 linear solves stopped at the sweep cap"), std::string::npos)
      << robots.out;
  EXPECT_NE(robots.out.find("--refine-coarse-piece-poses 30"), std::string::npos) << robots.out;
  const CommandResult pieces = RunMoslam(mit + " --refine-coarse-piece-poses 30");
  ASSERT_EQ(pieces.exit_code, 0) << pieces.out;
  EXPECT_EQ(pieces.out.find("--refine-coarse-piece-poses"), std::string::npos) << pieces.out;
  const CommandResult sweeps =
      RunMoslam(mit + " --refine-coarse-piece-poses 30 --refine-solver sweeps");
  EXPECT_NE(sweeps.exit_code, 0);
  EXPECT_NE(sweeps.out.find("coarse_piece_poses"), std::string::npos) << sweeps.out;
}

// `dgs --out DIR`: the distributed estimate as `solve --out DIR/` writes the centralized one (a
// g2o file per robot, each robot's vertices), and one TUM trajectory per robot; with --refine it
// is the centralized optimum (2.8e-7 m on blocks_world, measured).
TEST(CliDgs, OutWritesEachRobotsEstimateAndTrajectory) {
  const fs::path dir = moslam::test::ScratchDir("dgs_out");
  const fs::path dgs_out = dir / "dgs", solve_out = dir / "solve";
  const CommandResult r =
      RunMoslam("dgs " + kBlocksWorld + "4robots --refine --out " + dgs_out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  ASSERT_EQ(
      RunMoslam("solve " + kBlocksWorld + "4robots --out " + solve_out.string() + "/").exit_code,
      0);
  const moslam::Values distributed = moslam::ReadG2o(dgs_out.string()).initial;
  const moslam::Values centralized = moslam::ReadG2o(solve_out.string()).initial;
  ASSERT_EQ(distributed.size(), 64u);
  ASSERT_EQ(centralized.size(), 64u);
  EXPECT_LE(moslam::MaxPoseDifference(distributed, centralized), 1e-5);
  std::size_t rows = 0;
  for (int robot = 0; robot < 4; ++robot) {
    std::ifstream tum(dgs_out / ("robot_" + std::to_string(robot) + ".tum"));
    ASSERT_TRUE(tum) << "no trajectory of robot " << robot;
    for (std::string line; std::getline(tum, line);) {
      std::istringstream fields(line);
      double v = 0.0;
      int count = 0;
      while (fields >> v) ++count;
      EXPECT_EQ(count, 8) << line;  // timestamp (the pose index), x y z, qx qy qz qw
      ++rows;
    }
  }
  EXPECT_EQ(rows, 64u);
}

TEST(CliDgs, BadInputExitsOneWithAClearMessage) {
  const CommandResult split_folder = RunMoslam("dgs " + kBlocksWorld + "4robots --robots 2");
  EXPECT_EQ(split_folder.exit_code, 1);
  EXPECT_NE(split_folder.out.find("moslam: error: --robots 2 splits a single-robot file"),
            std::string::npos)
      << split_folder.out;
  const CommandResult eta = RunMoslam("dgs " + kBlocksWorld + "2robots --eta-rot -1");
  EXPECT_EQ(eta.exit_code, 1);
  EXPECT_NE(eta.out.find("eta_rotation"), std::string::npos) << eta.out;
  const CommandResult gamma = RunMoslam("dgs " + kBlocksWorld + "2robots --refine-gamma 2");
  EXPECT_EQ(gamma.exit_code, 1);
  EXPECT_NE(gamma.out.find("refinement.gamma"), std::string::npos) << gamma.out;
  const CommandResult halvings =
      RunMoslam("dgs " + kBlocksWorld + "2robots --refine-backtracks -1");
  EXPECT_EQ(halvings.exit_code, 1);
  EXPECT_NE(halvings.out.find("refinement.max_backtracks must be in [0, 30]"), std::string::npos)
      << halvings.out;
  // Refused, not read as "the solver's default".
  for (const char* tolerance : {"-1", "nan"}) {
    const CommandResult linear =
        RunMoslam("dgs " + kBlocksWorld + "2robots --refine " + "--refine-linear-tol " + tolerance);
    EXPECT_EQ(linear.exit_code, 1) << tolerance;
    EXPECT_NE(linear.out.find("refinement.sweep_tolerance must be finite and >= 0"),
              std::string::npos)
        << linear.out;
  }
  const CommandResult too_many =
      RunMoslam("dgs " MOSLAM_DATASETS_DIR "/pgo/tinyGrid3D.g2o --robots 20");  // 9 poses
  EXPECT_EQ(too_many.exit_code, 1);
  EXPECT_NE(too_many.out.find("moslam: error:"), std::string::npos) << too_many.out;
  EXPECT_NE(RunMoslam("dgs " MOSLAM_DATASETS_DIR "/pgo/tinyGrid3D.g2o --robots 70000").exit_code,
            0);
  const CommandResult missing = RunMoslam("dgs /nonexistent/folder");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.out.find("/nonexistent/folder"), std::string::npos) << missing.out;
  EXPECT_NE(RunMoslam("dgs " + kBlocksWorld + "2robots --order random").exit_code, 0);
  EXPECT_NE(RunMoslam("dgs " + kBlocksWorld + "2robots --robots 0").exit_code, 0);
  EXPECT_NE(RunMoslam("dgs").exit_code, 0);
}

// A two-robot folder with object landmarks (upper-case Symbol characters with --objects):
// object-object edges link the robots; ATE*/ARE* are reported for the objects too.
TEST(CliDgs, ObjectsAreReportedSeparately) {
  const fs::path dir = moslam::test::ScratchDir("dgs_objects");
  fs::remove_all(dir);
  fs::create_directories(dir);
  auto key = [](char c, int index) {
    return std::to_string((static_cast<unsigned long long>(c) << 56) |
                          static_cast<unsigned long long>(index));
  };
  auto edge = [](const std::string& a, const std::string& b, double x, double qz) {
    const double qw = std::sqrt(1.0 - qz * qz);
    return "EDGE_SE3:QUAT " + a + " " + b + " " + std::to_string(x) + " 0.1 0 0 0 " +
           std::to_string(qz) + " " + std::to_string(qw) + kI;
  };
  std::string files[2];
  for (int r = 0; r < 2; ++r) {
    const char pose = static_cast<char>('a' + r), object = static_cast<char>('A' + r);
    for (int i = 0; i < 5; ++i) {
      files[r] += edge(key(pose, i), key(pose, i + 1), 1.0 + 0.01 * i, 0.05 * (i % 2));
    }
    for (int k = 0; k < 2; ++k) {
      files[r] += edge(key(pose, 2 * k), key(object, k), 1.5, 0.1);
      files[r] += edge(key(pose, 2 * k + 3), key(object, k), -1.4, 0.12);
    }
  }
  for (int k = 0; k < 2; ++k) {  // separators: in both robots' files
    const std::string e = edge(key('B', k), key('A', k), 0.02, 0.01);
    files[0] += e;
    files[1] += e;
  }
  for (int r = 0; r < 2; ++r) std::ofstream(dir / (std::to_string(r) + ".g2o")) << files[r];
  const CommandResult r = RunMoslam("dgs " + dir.string() + " --objects --refine --json");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(LastLine(r.out));
  EXPECT_EQ(j["robots"], 2);
  EXPECT_EQ(j["objects"], 4);
  EXPECT_TRUE(j.contains("ate_objects"));
  EXPECT_TRUE(j.contains("are_objects_deg"));
  EXPECT_LE(j["ate_objects"].get<double>(), 1e-3);
  const double central = j["centralized_cost"].get<double>();
  EXPECT_LE(std::abs(j["final_cost"].get<double>() - central), 1e-4 * central);
  fs::remove_all(dir);
}

// `dgs --robust` on a spoiled blocks_world (4 robots, 30 % wrong separators, seed 1): the check
// leaves out exactly the wrong ones, one of them agrees with enough kept ones to be re-tested
// against the joint estimate and stays out; --no-retest-left-out skips the re-test.
TEST(CliDgs, RobustRetestsTheChecksRejectsUnlessToldNot) {
  const fs::path dir = moslam::test::ScratchDir("dgs_spoiled");
  fs::remove_all(dir);
  const CommandResult spoil =
      RunMoslam("spoil " + kBlocksWorld + "4robots --fraction 0.3 --seed 1 --out " + dir.string());
  ASSERT_EQ(spoil.exit_code, 0) << spoil.out;
  const std::string command =
      "dgs " + dir.string() + " --robust --gnc-threshold 1 --separator-test measurement";
  const std::string robust = command + " --json";
  const CommandResult r = RunMoslam(robust);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(LastLine(r.out));
  EXPECT_EQ(j["consistency_rejected"], 14);
  EXPECT_EQ(j["outliers"], 14);
  EXPECT_EQ(j["retests"], 1);
  EXPECT_EQ(j["retest_readmitted"], 0);
  const CommandResult off = RunMoslam(robust + " --no-retest-left-out");
  ASSERT_EQ(off.exit_code, 0) << off.out;
  const auto k = nlohmann::json::parse(LastLine(off.out));
  EXPECT_EQ(k["retests"], 0);
  EXPECT_EQ(k["outliers"], 14);
  EXPECT_LT(k["bytes"].get<long long>(), j["bytes"].get<long long>());
  // Without --json: the same counts as a report.
  const CommandResult text = RunMoslam(command);
  ASSERT_EQ(text.exit_code, 0) << text.out;
  EXPECT_EQ(text.out.find('{'), std::string::npos) << text.out;
  for (const std::string& line :
       {std::string("robots' GNC:     all inliers after 0 round(s); 14 rejected in all (0 weight"),
        std::string("separator check: 14 rejected before GNC"),
        std::string("re-tested against the joint estimate: 1 left-out separator(s), 0 back"),
        "traffic: " + std::to_string(j["bytes"].get<long long>()) + " bytes"}) {
    EXPECT_NE(text.out.find(line), std::string::npos) << line << " not in\n" << text.out;
  }
  fs::remove_all(dir);
}

// The factors a robust solve's JSON lists as rejected, and those `spoil` wrote to outliers.txt in
// `folder`, as pairs of key names.
using FactorPairs = std::set<std::pair<std::string, std::string>>;
FactorPairs RejectedPairs(const nlohmann::json& robust) {
  FactorPairs out;
  for (const auto& pair : robust["rejected"]) {
    out.insert({pair[0].get<std::string>(), pair[1].get<std::string>()});
  }
  return out;
}
FactorPairs SpoiledPairs(const fs::path& folder) {
  FactorPairs out;
  std::ifstream list(folder / "outliers.txt");
  for (std::string a, b; list >> a >> b;) out.insert({a, b});
  return out;
}

// `spoil` of a single-robot 2D file (CSAIL, 30 %): wrong loop closures, written back in 2D;
// `solve --robust` at threshold 5 (CSAIL's information is far larger than its noise), its loop
// closures checked through the odometry, rejects exactly the ones listed in outliers.txt and
// writes the clean file's optimum (GNC alone ends 85 m from it: README).
TEST(CliSolve, RobustRejectsTheWrongLoopClosuresSpoilAddsToOneRobot) {
  const fs::path dir = moslam::test::ScratchDir("spoiled");
  const fs::path spoiled = dir / "spoiled", robust_out = dir / "robust", clean_out = dir / "clean";
  const std::string csail = MOSLAM_DATASETS_DIR "/pgo/CSAIL.g2o";
  const CommandResult spoil =
      RunMoslam("spoil " + csail + " --fraction 0.3 --seed 1 --out " + spoiled.string());
  ASSERT_EQ(spoil.exit_code, 0) << spoil.out;
  EXPECT_NE(spoil.out.find("128 loop closures, 55 wrong ones added"), std::string::npos)
      << spoil.out;
  std::ifstream file(spoiled / "0.g2o");
  std::string tag;
  file >> tag;
  EXPECT_EQ(tag, "EDGE_SE2");
  const CommandResult r =
      RunMoslam("solve " + spoiled.string() + " --robust --gnc-threshold 5 --json --out " +
                robust_out.string() + "/");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto robust = nlohmann::json::parse(LastLine(r.out))["robust"];
  EXPECT_EQ(robust["robust_factors"], 183);
  EXPECT_EQ(robust["check_checked"], 183);  // every loop closure, through the odometry
  EXPECT_EQ(robust["check_rejected"], 55);
  const FactorPairs rejected = RejectedPairs(robust);
  const FactorPairs injected = SpoiledPairs(spoiled);
  EXPECT_EQ(injected.size(), 55u);
  EXPECT_EQ(rejected, injected);
  ASSERT_EQ(RunMoslam("solve " + csail + " --out " + clean_out.string() + "/").exit_code, 0);
  // Robot 0's poses, as Symbols in the spoiled folder and plain integers in the clean file.
  const moslam::Values clean = moslam::ReadG2o(clean_out.string()).initial;
  const moslam::Values estimate = moslam::ReadG2o(robust_out.string()).initial;
  ASSERT_EQ(clean.size(), estimate.size());
  EXPECT_LE(moslam::MaxPoseDifference(estimate, clean), 1e-6);
}

// A pair of key names as the indices of their poses (the robot letter dropped): a split file's
// keys name its blocks, the spoiled folder's robot 0.
std::set<std::pair<long, long>> PoseIndices(const FactorPairs& pairs) {
  std::set<std::pair<long, long>> out;
  for (const auto& [a, b] : pairs) {
    const long i = std::stol(a.substr(1)), j = std::stol(b.substr(1));
    out.insert({std::min(i, j), std::max(i, j)});
  }
  return out;
}

// `dgs <one robot's file> --robots 2 --robust`: the file's loop closures are the robust factors,
// in a block (29 of the 55 wrong ones: each robot checks its own through its odometry) or between
// the two (26: the separator check), and the odometry stays least squares, from one block to the
// next too. The robots reject exactly the wrong ones and reach the clean file's optimum, as
// `solve --robust` does (above). Before, only the factors between the blocks were robust (the
// odometry between them included), and the wrong loop closures inside a block bent the map.
// The refinement runs to 1e-12 of the cost: CSAIL's optimum is flat, and at the default 1e-10 it
// stops 9e-6 m from it at 4.6e-13 of its cost (commit 7b22866; 3e-9 m at 1e-12).
TEST(CliDgs, RobustOnASplitFileRejectsTheWrongLoopClosuresInAndBetweenBlocks) {
  const fs::path dir = moslam::test::ScratchDir("split_robust");
  const fs::path spoiled = dir / "spoiled", robust_out = dir / "robust", clean_out = dir / "clean";
  const std::string csail = MOSLAM_DATASETS_DIR "/pgo/CSAIL.g2o";
  ASSERT_EQ(
      RunMoslam("spoil " + csail + " --fraction 0.3 --seed 1 --out " + spoiled.string()).exit_code,
      0);
  const CommandResult r =
      RunMoslam("dgs " + (spoiled / "0.g2o").string() +
                " --robots 2 --robust --gnc-threshold 5 --refine-tol 1e-12 --json --out " +
                robust_out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto j = nlohmann::json::parse(LastLine(r.out));
  EXPECT_EQ(j["robust_factors"], 183);  // the loop closures: not the odometry
  EXPECT_EQ(j["outliers"], 55);
  EXPECT_EQ(j["weights_disagreeing"], 0);
  EXPECT_EQ(PoseIndices(RejectedPairs(j)), PoseIndices(SpoiledPairs(spoiled)));
  ASSERT_EQ(RunMoslam("solve " + csail + " --out " + clean_out.string() + "/").exit_code, 0);
  const moslam::Values clean = moslam::ReadG2o(clean_out.string()).initial;
  moslam::Values estimate;  // the blocks' poses as robot 0's
  for (const auto& [k, x] : moslam::ReadG2o(robust_out.string()).initial) {
    estimate[moslam::Key::Pose(0, k.index)] = x;
  }
  ASSERT_EQ(clean.size(), estimate.size());
  EXPECT_LE(moslam::MaxPoseDifference(estimate, clean), 1e-6);
  fs::remove_all(dir);
}

// `solve --robust`, the centralized reference of `dgs --robust`, on the spoiled blocks_world of
// the test above: it rejects exactly the separators `spoil` wrote to outliers.txt, and the
// estimate it writes is the clean folder's least-squares optimum; on the clean folder it rejects
// nothing and equals least squares.
TEST(CliSolve, RobustRejectsTheSpoiledSeparatorsAndReachesTheCleanOptimum) {
  const fs::path dir = moslam::test::ScratchDir("solve_spoiled");
  fs::remove_all(dir);
  const fs::path spoiled = dir / "spoiled", robust_out = dir / "robust", clean_out = dir / "clean";
  const CommandResult spoil = RunMoslam(
      "spoil " + kBlocksWorld + "4robots --fraction 0.3 --seed 1 --out " + spoiled.string());
  ASSERT_EQ(spoil.exit_code, 0) << spoil.out;
  const std::string options = " --robust --gnc-threshold 1 --separator-test measurement --json";
  const CommandResult r =
      RunMoslam("solve " + spoiled.string() + options + " --out " + robust_out.string() + "/");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto robust = nlohmann::json::parse(LastLine(r.out))["robust"];
  const FactorPairs rejected = RejectedPairs(robust);
  const FactorPairs injected = SpoiledPairs(spoiled);
  EXPECT_EQ(injected.size(), 14u);
  EXPECT_EQ(rejected, injected);
  EXPECT_EQ(robust["outliers"], 14);
  EXPECT_EQ(robust["check_checked"], 46);  // the separators of the 4 robots' pairs
  EXPECT_EQ(robust["check_rejected"], 14);

  const CommandResult clean =
      RunMoslam("solve " + kBlocksWorld + "4robots --json --out " + clean_out.string() + "/");
  ASSERT_EQ(clean.exit_code, 0) << clean.out;
  const moslam::Values clean_estimate = moslam::ReadG2o(clean_out.string()).initial;
  ASSERT_EQ(clean_estimate.size(), 64u);
  EXPECT_LE(moslam::MaxPoseDifference(moslam::ReadG2o(robust_out.string()).initial, clean_estimate),
            1e-5);

  const CommandResult on_clean = RunMoslam("solve " + kBlocksWorld + "4robots" + options);
  ASSERT_EQ(on_clean.exit_code, 0) << on_clean.out;
  const auto k = nlohmann::json::parse(LastLine(on_clean.out));
  EXPECT_EQ(k["robust"]["outliers"], 0);
  EXPECT_NEAR(k["final_cost"].get<double>(),
              nlohmann::json::parse(LastLine(clean.out))["final_cost"].get<double>(), 1e-9);
  fs::remove_all(dir);
}

}  // namespace

// `moslam simulate`: one small run end to end, the documented JSON, the Fig. 4 plot, bad input.
TEST(CliSimulate, RunsEndToEndWithJsonAndPlot) {
  const fs::path svg = moslam::test::ScratchDir("simulate") / "simulate.svg";
  fs::remove(svg);
  const CommandResult r = RunMoslam(
      "simulate --scenario chairs25 --robots 2 --runs 2 --poses 30 --seed 3 --table all --json "
      "--plot " + svg.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("| Robots"), std::string::npos) << r.out;  // the Markdown tables
  const auto j = nlohmann::json::parse(LastLine(r.out));
  ASSERT_EQ(j["rows"].size(), 1u);
  const auto& row = j["rows"][0];
  EXPECT_EQ(row["config"]["robots"], 2);
  ASSERT_EQ(row["runs"].size(), 2u);
  for (const auto& run : row["runs"]) {
    for (const char* key : {"iterations_eta1", "cost_eta1", "iterations_eta2", "cost_eta2",
                            "gn_cost", "refined_cost", "ate_star_poses", "are_star_poses",
                            "ate_star_landmarks", "inter_precision", "rendezvous_bytes"}) {
      ASSERT_TRUE(run.contains(key)) << key;
    }
    const double gn = run["gn_cost"].get<double>();
    EXPECT_LE(run["refined_cost"].get<double>(), gn * (1.0 + 1e-4));
    EXPECT_GE(run["cost_eta1"].get<double>(), gn * (1.0 - 1e-9));
  }
  const std::string head = moslam::ReadWholeFileOrThrow(svg.string());
  EXPECT_NE(head.find("<svg"), std::string::npos);
  fs::remove(svg);
  // The same seed gives the same numbers.
  const CommandResult again = RunMoslam(
      "simulate --scenario chairs25 --robots 2 --runs 2 --poses 30 --seed 3 --json");
  ASSERT_EQ(again.exit_code, 0) << again.out;
  const auto k = nlohmann::json::parse(LastLine(again.out));
  EXPECT_EQ(k["rows"][0]["runs"][1]["gn_cost"], row["runs"][1]["gn_cost"]);
}

// `simulate --online`: the mission with a group solve at every rendezvous, run with the flags it
// is given (the library's OnlineExperiment tests measure the mission itself). Robust, with 30 %
// wrong pairs injected and unknown initial poses, this seed sets aside every wrong pair and no
// right one (measured: 7 of 7).
TEST(CliSimulate, OnlineRunsTheMissionWithTheFlagsItIsGiven) {
  const std::string run =
      "simulate --online --scenario chairs25 --robots 3 --runs 1 --poses 40 --seed 1 --json";
  const CommandResult plain = RunMoslam(run);
  ASSERT_EQ(plain.exit_code, 0) << plain.out;
  EXPECT_NE(plain.out.find("| online / batch: median robot |"), std::string::npos) << plain.out;
  const auto row = nlohmann::json::parse(LastLine(plain.out))["rows"][0];
  EXPECT_EQ(row["config"]["robust"], false);
  EXPECT_EQ(row["config"]["known_initial_poses"], true);
  EXPECT_EQ(row["config"]["poses_per_robot"], 40);
  EXPECT_FALSE(row["runs"][0]["points"].empty());
  EXPECT_EQ(row["runs"][0]["online_ate"].size(), 3u);

  const fs::path svg = moslam::test::ScratchDir("simulate_online") / "online.svg";
  fs::remove(svg);
  const CommandResult robust =
      RunMoslam(run + " --robust --outliers 0.3 --initial-poses unknown --plot " + svg.string());
  ASSERT_EQ(robust.exit_code, 0) << robust.out;
  EXPECT_NE(robust.out.find("| set aside / run: wrong |"), std::string::npos) << robust.out;
  const auto r = nlohmann::json::parse(LastLine(robust.out))["rows"][0];
  EXPECT_EQ(r["config"]["robust"], true);
  EXPECT_EQ(r["config"]["known_initial_poses"], false);
  EXPECT_EQ(r["config"]["outlier_fraction"], 0.3);
  const auto& m = r["runs"][0];
  EXPECT_GT(m["injected"].get<double>(), 0.0);
  EXPECT_GT(m["wrong_pairs"].get<double>(), 0.0);
  EXPECT_EQ(m["set_aside_wrong"], m["wrong_pairs"]);
  EXPECT_EQ(m["set_aside"], m["set_aside_wrong"]);
  const std::string plot = moslam::ReadWholeFileOrThrow(svg.string());
  EXPECT_NE(plot.find("<polyline"), std::string::npos);
  fs::remove(svg);
}

// The robots' loop closure: off with sampled measurements (the paper's rule, Tables 1-3) unless
// asked for; the two flags exclude each other.
TEST(CliSimulate, LoopClosureIsOffWithSampledMeasurementsUnlessAskedFor) {
  const std::string run =
      "simulate --scenario chairs25 --robots 2 --runs 1 --poses 30 --seed 3 --json";
  const CommandResult paper = RunMoslam(run);
  ASSERT_EQ(paper.exit_code, 0) << paper.out;
  const auto config = nlohmann::json::parse(LastLine(paper.out))["rows"][0]["config"];
  EXPECT_EQ(config["loop_closure"], false);
  EXPECT_EQ(config["exclusion_radius"], 0.0);
  EXPECT_EQ(config["ambiguity_ratio"], 0.0);
  EXPECT_EQ(config["covariance_gate"], 0.0);
  const CommandResult gated = RunMoslam(run + " --covariance-gate 22.46");
  ASSERT_EQ(gated.exit_code, 0) << gated.out;
  EXPECT_EQ(nlohmann::json::parse(LastLine(gated.out))["rows"][0]["config"]["covariance_gate"],
            22.46);
  const CommandResult asked = RunMoslam(run + " --loop-closure");
  ASSERT_EQ(asked.exit_code, 0) << asked.out;
  EXPECT_EQ(nlohmann::json::parse(LastLine(asked.out))["rows"][0]["config"]["loop_closure"], true);
  const CommandResult refused = RunMoslam(run + " --no-loop-closure");
  ASSERT_EQ(refused.exit_code, 0) << refused.out;
  EXPECT_EQ(nlohmann::json::parse(LastLine(refused.out))["rows"][0]["config"]["loop_closure"],
            false);
  const CommandResult both = RunMoslam(run + " --loop-closure --no-loop-closure");
  EXPECT_NE(both.exit_code, 0) << both.out;
  EXPECT_NE(both.out.find("excludes"), std::string::npos) << both.out;
}

// The rendezvous' refinement by the constellation of both maps: off with sampled measurements
// (Tables 1-3's procedure) unless asked for; the two flags exclude each other; refused online.
TEST(CliSimulate, RendezvousConstellationIsOffWithSampledMeasurementsUnlessAskedFor) {
  const std::string run =
      "simulate --scenario chairs25 --robots 2 --runs 1 --poses 30 --seed 3 --json";
  const auto constellation = [](const CommandResult& r) {
    return nlohmann::json::parse(LastLine(r.out))["rows"][0]["config"]["rendezvous_constellation"];
  };
  const CommandResult paper = RunMoslam(run);
  ASSERT_EQ(paper.exit_code, 0) << paper.out;
  EXPECT_EQ(constellation(paper), false);
  const CommandResult asked = RunMoslam(run + " --rendezvous-constellation");
  ASSERT_EQ(asked.exit_code, 0) << asked.out;
  EXPECT_EQ(constellation(asked), true);
  const CommandResult refused = RunMoslam(run + " --no-rendezvous-constellation");
  ASSERT_EQ(refused.exit_code, 0) << refused.out;
  EXPECT_EQ(constellation(refused), false);
  const CommandResult both =
      RunMoslam(run + " --rendezvous-constellation --no-rendezvous-constellation");
  EXPECT_NE(both.exit_code, 0) << both.out;
  EXPECT_NE(both.out.find("excludes"), std::string::npos) << both.out;
  const CommandResult online = RunMoslam(
      "simulate --online --scenario chairs25 --robots 2 --runs 1 --rendezvous-constellation");
  EXPECT_EQ(online.exit_code, 1) << online.out;
  EXPECT_NE(online.out.find("--rendezvous-constellation are not part of the online mission"),
            std::string::npos)
      << online.out;
  // With unknown initial poses there is no known transform to refine: refused, not ignored.
  for (const std::string& command :
       {run, std::string("team --scenario chairs25 --robots 2"),
        std::string("robot --robot 0 --scenario chairs25 --robots 2")}) {
    const CommandResult r =
        RunMoslam(command + " --initial-poses unknown --rendezvous-constellation");
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find("refines the transform of known initial poses"), std::string::npos)
        << r.out;
  }
  // The robot processes take the flag too (Team.RendezvousConstellation...), not online, and
  // not without a scenario: with --data every scenario flag is refused, not ignored.
  const std::string folder = fs::temp_directory_path().string();
  for (const std::string& command :
       {"team --data " + folder, "robot --robot 0 --data " + folder}) {
    for (const char* flag : {"--rendezvous-constellation", "--loop-closure", "--seed 3"}) {
      const CommandResult r = RunMoslam(command + " " + flag);
      EXPECT_NE(r.exit_code, 0) << command << " " << flag << ": " << r.out;
      EXPECT_NE(r.out.find("requires --scenario"), std::string::npos) << r.out;
    }
  }
  for (const char* command : {"team --scenario chairs25 --robots 2",
                              "robot --robot 0 --scenario chairs25 --robots 2"}) {
    const CommandResult r =
        RunMoslam(std::string(command) + " --online --rendezvous-constellation");
    EXPECT_EQ(r.exit_code, 1) << r.out;
    EXPECT_NE(r.out.find("--rendezvous-constellation are not part of the online mission"),
              std::string::npos)
        << r.out;
  }
}

TEST(CliSimulate, BadInputExitsOneWithAClearMessage) {
  const CommandResult mismatch =
      RunMoslam("simulate --robots 2 --runs 1 --sigma-rot 1 5 --sigma-trans 0.1");
  EXPECT_EQ(mismatch.exit_code, 1) << mismatch.out;
  EXPECT_NE(mismatch.out.find("--sigma-trans"), std::string::npos) << mismatch.out;
  EXPECT_NE(RunMoslam("simulate --scenario mars").exit_code, 0);
  EXPECT_NE(RunMoslam("simulate --robots 0").exit_code, 0);
  // A plot that cannot be written is refused before the runs (10 of house's would take a minute).
  const std::string runs = "simulate --scenario house --robots 6 --runs 10 --plot ";
  const CommandResult no_folder = RunMoslam(runs + "/nonexistent/moslam/plot.svg");
  EXPECT_EQ(no_folder.exit_code, 1) << no_folder.out;
  EXPECT_NE(no_folder.out.find("no folder '/nonexistent/moslam' to write it in"), std::string::npos)
      << no_folder.out;
  const CommandResult folder = RunMoslam(runs + moslam::test::ScratchDir("plot_folder").string());
  EXPECT_EQ(folder.exit_code, 1) << folder.out;
  EXPECT_NE(folder.out.find("is a folder; give a file name"), std::string::npos) << folder.out;
}

// --detection-log: every detection of every run as a JSON line, with its ground-truth evaluation;
// refused without rendered perception, whose detections it logs.
TEST(CliSimulate, RenderedPerceptionLogsEveryDetection) {
  const fs::path log = moslam::test::ScratchDir("detections") / "detections.jsonl";
  fs::remove(log);
  const CommandResult sampled = RunMoslam("simulate --robots 2 --runs 1 --detection-log " +
                                          log.string());
  EXPECT_EQ(sampled.exit_code, 1) << sampled.out;
  EXPECT_NE(sampled.out.find("--detection-log needs --perception rendered"), std::string::npos)
      << sampled.out;
  const CommandResult r = RunMoslam(
      "simulate --scenario chairs25 --robots 1 --runs 1 --poses 3 --perception rendered "
      "--template-cache none --table perception --json --detection-log " + log.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto row = nlohmann::json::parse(LastLine(r.out))["rows"][0];
  // Rendered perception's defaults: the exclusion radius, the ambiguity test, the robots' loop
  // closure and the rendezvous' refinement by the constellation.
  EXPECT_EQ(row["config"]["perception"], "rendered");
  EXPECT_EQ(row["config"]["exclusion_radius"], 0.5);
  EXPECT_EQ(row["config"]["ambiguity_ratio"], 0.6);
  EXPECT_EQ(row["config"]["loop_closure"], true);
  EXPECT_EQ(row["config"]["rendezvous_constellation"], true);
  const auto run = row["runs"][0];
  std::ifstream in(log);
  std::string line;
  int lines = 0, accepted = 0;
  while (std::getline(in, line)) {
    const auto d = nlohmann::json::parse(line);
    ++lines;
    EXPECT_EQ(d["scenario"], "chairs25");
    EXPECT_EQ(d["run"], 0);
    EXPECT_FALSE(d["label"].get<std::string>().empty());
    for (const char* key : {"robot", "pose", "status", "object", "depth", "translation_error",
                            "inliers", "geometric_agreement", "covered_agreement"}) {
      EXPECT_TRUE(d.contains(key)) << key << " missing in " << line;
    }
    if (d["status"] == "accepted") ++accepted;
  }
  EXPECT_GT(lines, 0);
  EXPECT_EQ(lines, run["perception_detections"].get<int>()) << r.out;
  EXPECT_EQ(accepted, run["perception_accepted"].get<int>()) << r.out;
  fs::remove(log);
}

// --perception-cache: the second run of a seed is replayed (perception_cached 1), with the same
// numbers; refused with sampled measurements and beside --detection-log.
TEST(CliSimulate, PerceptionCacheReplaysARenderedRun) {
  const fs::path dir = moslam::test::ScratchDir("perception_cache");
  fs::remove_all(dir);
  const std::string command =
      "simulate --scenario chairs25 --robots 1 --runs 1 --poses 3 --perception rendered "
      "--template-cache none --table perception --json --perception-cache " + dir.string();
  const CommandResult first = RunMoslam(command);
  ASSERT_EQ(first.exit_code, 0) << first.out;
  const CommandResult second = RunMoslam(command);
  ASSERT_EQ(second.exit_code, 0) << second.out;
  const auto a = nlohmann::json::parse(LastLine(first.out))["rows"][0]["runs"][0];
  const auto b = nlohmann::json::parse(LastLine(second.out))["rows"][0]["runs"][0];
  EXPECT_EQ(a["perception_cached"], 0.0);
  EXPECT_EQ(b["perception_cached"], 1.0);
  for (const char* key : {"perception_detections", "perception_accepted", "landmarks",
                          "gn_cost", "gn_ate_poses"}) {
    EXPECT_EQ(a[key], b[key]) << key;
  }
  const CommandResult sampled =
      RunMoslam("simulate --robots 2 --runs 1 --perception-cache " + dir.string());
  EXPECT_EQ(sampled.exit_code, 1) << sampled.out;
  EXPECT_NE(sampled.out.find("--perception-cache needs --perception rendered"),
            std::string::npos) << sampled.out;
  const CommandResult both = RunMoslam(command + " --detection-log " + (dir / "log").string());
  EXPECT_EQ(both.exit_code, 1) << both.out;
  EXPECT_NE(both.out.find("--detection-log and --perception-cache"), std::string::npos)
      << both.out;
  const CommandResult no_templates = RunMoslam(command + " --templates " + (dir / "none").string());
  EXPECT_EQ(no_templates.exit_code, 1) << no_templates.out;
  EXPECT_NE(no_templates.out.find("none"), std::string::npos) << no_templates.out;
  fs::remove_all(dir);
}

// --perception visible: the objects the rendered frames show, measured with the paper's noise (the
// ideal front-end, render/visible_sensing.h), with the robots of sampled measurements; no
// perception table (it has no detections); its options refused without it.
TEST(CliSimulate, VisiblePerceptionMeasuresWhatTheFramesShow) {
  const std::string command =
      "simulate --scenario house --robots 1 --runs 1 --poses 20 --table association --json";
  const CommandResult sampled = RunMoslam(command);
  ASSERT_EQ(sampled.exit_code, 0) << sampled.out;
  const CommandResult visible = RunMoslam(command + " --perception visible");
  ASSERT_EQ(visible.exit_code, 0) << visible.out;
  const auto a = nlohmann::json::parse(LastLine(sampled.out))["rows"][0];
  const auto b = nlohmann::json::parse(LastLine(visible.out))["rows"][0];
  EXPECT_EQ(a["config"]["perception"], "sampled");
  EXPECT_EQ(b["config"]["perception"], "visible");
  EXPECT_EQ(b["config"]["loop_closure"], false);
  EXPECT_EQ(b["config"]["exclusion_radius"], 0.0);
  EXPECT_EQ(b["config"]["ambiguity_ratio"], 0.0);
  EXPECT_EQ(b["runs"][0]["perception_frames"], 20.0);
  // house has walls: the frames show fewer objects than the sampled camera measures through them.
  const double sampled_per_pose = a["runs"][0]["measurements_per_pose"].get<double>();
  const double visible_per_pose = b["runs"][0]["measurements_per_pose"].get<double>();
  EXPECT_GT(visible_per_pose, 0.0);
  EXPECT_LT(visible_per_pose, sampled_per_pose);
  EXPECT_NE(visible.out.find("object measurements of the 20 frames"), std::string::npos)
      << visible.out;
  const CommandResult table = RunMoslam(command + " --perception visible --table perception");
  EXPECT_EQ(table.exit_code, 1) << table.out;
  EXPECT_NE(table.out.find("--perception visible has none"), std::string::npos) << table.out;
  const CommandResult scaled = RunMoslam(command + " --visible-noise 1 0.01");
  EXPECT_EQ(scaled.exit_code, 1) << scaled.out;
  EXPECT_NE(scaled.out.find("--visible-noise and --visible-keep need"), std::string::npos)
      << scaled.out;
}

// The pose-graph executable loads nothing of the perception or middleware stacks (apps/cli.h):
// its shared libraries, as the dynamic loader resolves them.
TEST(CliExecutables, PoseGraphCommandsLoadNoPerceptionOrDdsLibrary) {
  const CommandResult ldd = RunShell(std::string("ldd ") + MOSLAM_BINARY);
  ASSERT_EQ(ldd.exit_code, 0) << ldd.out;
  const std::string& out = ldd.out;
  ASSERT_NE(out.find("libc.so"), std::string::npos) << out;  // ldd did list the libraries
  for (const char* forbidden : {"libpcl", "libvtk", "libopencv", "libddsc", "libgomp"}) {
    EXPECT_EQ(out.find(forbidden), std::string::npos) << forbidden << " in\n" << out;
  }
}

// Commands of the other executables run through `moslam` with their own options and help.
TEST(CliExecutables, PerceptionAndRobotCommandsRunThroughMoslam) {
  const CommandResult render = RunMoslam("render --help");
  EXPECT_EQ(render.exit_code, 0) << render.out;
  EXPECT_NE(render.out.find("--scenario"), std::string::npos) << render.out;
  const CommandResult team = RunMoslam("team --help");
  EXPECT_EQ(team.exit_code, 0) << team.out;
  EXPECT_NE(team.out.find("--data"), std::string::npos) << team.out;
  // A real run and its error path, reported by the perception executable: the class names
  // beside a model that does not exist.
  const CommandResult detect = RunMoslam("detect --model /nonexistent/m.onnx --image /x.png");
  EXPECT_EQ(detect.exit_code, 1) << detect.out;
  EXPECT_NE(detect.out.find("moslam: error: cannot read class names file '/nonexistent/"),
            std::string::npos)
      << detect.out;
  // Without --model, the committed detector (as perceive and simulate use it): the model loads
  // and the missing image is the error.
  const CommandResult committed = RunMoslam("detect --image /nonexistent/x.png");
  EXPECT_EQ(committed.exit_code, 1) << committed.out;
  EXPECT_NE(committed.out.find("moslam: error: cannot read image '/nonexistent/x.png'"),
            std::string::npos)
      << committed.out;
}

// `moslam render` of one robot's first `poses` views of chairs25 into `dir` (`format`: yolo or
// tum).
CommandResult RenderChairs25(const fs::path& dir, const std::string& format, int poses) {
  return RunMoslam("render --scenario chairs25 --robots 1 --poses " + std::to_string(poses) +
                   " --format " + format + " --out " + dir.string());
}

// `detect` on rendered frames (a YOLO-layout dataset `render` writes, with ignore regions): the
// evaluation's counts agree with its precision and recall, the committed detector finds most
// chairs (0.84 / 0.84 strict, 0.93 / 0.84 with the ignore regions on this seed, measured), and
// on one image it lists its boxes and writes the annotated image.
TEST(CliDetect, EvaluatesARenderedDatasetAndDetectsOnAnImage) {
  const fs::path dir = moslam::test::ScratchDir("detect");
  fs::remove_all(dir);
  const CommandResult render = RenderChairs25(dir, "yolo", 4);
  ASSERT_EQ(render.exit_code, 0) << render.out;
  const CommandResult data = RunMoslam("detect --data " + dir.string() + " --json");
  ASSERT_EQ(data.exit_code, 0) << data.out;
  const auto m = nlohmann::json::parse(LastLine(data.out));
  EXPECT_EQ(m["frames"], 4);
  const double tp = m["true_positives"].get<double>(), fp = m["false_positives"].get<double>();
  const double gt = m["ground_truths"].get<double>();
  ASSERT_GT(gt, 0.0);
  EXPECT_NEAR(m["precision"].get<double>(), tp / (tp + fp), 1e-12);
  EXPECT_NEAR(m["recall"].get<double>(), tp / gt, 1e-12);
  EXPECT_GE(m["precision"].get<double>(), 0.7);
  EXPECT_GE(m["recall"].get<double>(), 0.7);
  const auto& ignore = m["with_ignore"];
  EXPECT_GT(ignore["ignore_boxes"].get<int>(), 0);
  EXPECT_GE(ignore["precision"].get<double>(), m["precision"].get<double>());
  EXPECT_EQ(ignore["recall"], m["recall"]);
  // Without --json: the same counts as a table per protocol; --annotate: every image annotated
  // under its own name.
  const fs::path annotated_folder = dir / "annotated";
  const CommandResult table =
      RunMoslam("detect --data " + dir.string() + " --annotate " + annotated_folder.string());
  ASSERT_EQ(table.exit_code, 0) << table.out;
  EXPECT_NE(table.out.find("strict (every detection that matches no label"), std::string::npos)
      << table.out;
  EXPECT_NE(table.out.find("with ignore regions"), std::string::npos) << table.out;
  char all[64];
  std::snprintf(all, sizeof(all), "%6d %6d", m["true_positives"].get<int>(),
                m["false_positives"].get<int>());
  EXPECT_NE(table.out.find(all), std::string::npos) << all << " not in\n" << table.out;
  int drawn_on = 0;  // images whose annotated copy differs (both PNGs written by OpenCV)
  for (const fs::directory_entry& image : fs::directory_iterator(dir / "images")) {
    const fs::path copy = annotated_folder / image.path().filename();
    ASSERT_TRUE(fs::exists(copy)) << copy << " not written";
    drawn_on += moslam::ReadWholeFileOrThrow(copy.string()) !=
                        moslam::ReadWholeFileOrThrow(image.path().string())
                    ? 1
                    : 0;
  }
  EXPECT_GT(drawn_on, 0);

  const fs::path annotated = dir / "annotated.png";
  const CommandResult image =
      RunMoslam("detect --image " + (dir / "images" / "000000.png").string() +
                " --json --annotate " + annotated.string());
  ASSERT_EQ(image.exit_code, 0) << image.out;
  const auto detections = nlohmann::json::parse(LastLine(image.out))["detections"];
  ASSERT_FALSE(detections.empty());
  for (const auto& d : detections) {
    EXPECT_EQ(d["box"].size(), 4u);
    EXPECT_GE(d["confidence"].get<double>(), 0.3);
    EXPECT_FALSE(d["label"].get<std::string>().empty());
  }
  EXPECT_GT(fs::file_size(annotated), 0u);
  // An annotated image whose extension names no format OpenCV writes: a clear error.
  const CommandResult unknown =
      RunMoslam("detect --image " + (dir / "images" / "000000.png").string() + " --annotate " +
                (dir / "annotated.xyz").string());
  EXPECT_EQ(unknown.exit_code, 1) << unknown.out;
  EXPECT_NE(unknown.out.find("moslam: error: cannot write annotated image"), std::string::npos)
      << unknown.out;
  EXPECT_NE(unknown.out.find("no writer for its extension"), std::string::npos) << unknown.out;
  fs::remove_all(dir);
}

// `perceive` against the world `render` wrote: every accepted pose is evaluated against its true
// object, at the front-end's accuracy (the median 1.1 cm / 1.7 deg here, measured; the issue's
// 2 cm / 2 deg is over the held-out sequences), every frame's objects are written to --out and
// every frame annotated.
TEST(CliPerceive, EvaluatesThePosesAgainstTheWorldAndWritesEveryFrame) {
  const fs::path dir = moslam::test::ScratchDir("perceive_world");
  fs::remove_all(dir);
  const CommandResult render = RenderChairs25(dir, "tum", 3);
  ASSERT_EQ(render.exit_code, 0) << render.out;
  const fs::path out = dir / "perceived.json", annotated = dir / "annotated";
  const CommandResult r =
      RunMoslam("perceive " + (dir / "robot0").string() + " --world " +
                (dir / "world.json").string() + " --template-cache none" + " --json --out " +
                out.string() + " --annotate " + annotated.string());
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const auto s = nlohmann::json::parse(LastLine(r.out));
  EXPECT_EQ(s["frames"], 3);
  ASSERT_GT(s["accepted"].get<int>(), 0);
  EXPECT_EQ(s["evaluated"], s["accepted"]);
  EXPECT_LE(s["median_translation_error"].get<double>(), 0.05);
  EXPECT_LE(s["median_rotation_error_deg"].get<double>(), 5.0);
  std::ifstream in(out);
  const auto written = nlohmann::json::parse(in);
  ASSERT_EQ(written["frames"].size(), 3u);
  int accepted = 0;
  for (const auto& frame : written["frames"]) {
    for (const auto& o : frame["objects"]) {
      if (o["status"] != "accepted") continue;
      ++accepted;
      EXPECT_GE(o["ground_truth"]["object"].get<int>(), 0);
    }
  }
  EXPECT_EQ(accepted, s["accepted"].get<int>());
  int images = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(annotated)) ++images;
  EXPECT_EQ(images, 3);
  // Without --json: the summary's counts and errors in words.
  const CommandResult words = RunMoslam("perceive " + (dir / "robot0").string() + " --world " +
                                        (dir / "world.json").string() + " --template-cache none");
  ASSERT_EQ(words.exit_code, 0) << words.out;
  EXPECT_NE(
      words.out.find("3 frames, " + std::to_string(s["detections"].get<int>()) + " detections, " +
                     std::to_string(s["accepted"].get<int>()) + " accepted"),
      std::string::npos)
      << words.out;
  EXPECT_NE(words.out.find("pose error against ground truth"), std::string::npos) << words.out;
  fs::remove_all(dir);
}

// `perceive` takes the detector's operating point as `detect` does (apps/detector_flags.h) and
// reports it in its summary; out-of-range values are refused before any work.
TEST(CliPerceive, TakesTheDetectorsOperatingPoint) {
  const fs::path dir = moslam::test::ScratchDir("perceive");
  fs::remove_all(dir);
  const CommandResult render = RenderChairs25(dir, "tum", 1);
  ASSERT_EQ(render.exit_code, 0) << render.out;
  const std::string seq = (dir / "robot0").string();
  const CommandResult fallback = RunMoslam("perceive " + seq + " --template-cache none --json");
  ASSERT_EQ(fallback.exit_code, 0) << fallback.out;
  const auto d = nlohmann::json::parse(LastLine(fallback.out))["detector"];
  EXPECT_NEAR(d["threshold"].get<double>(), 0.3, 1e-6);
  EXPECT_NEAR(d["nms"].get<double>(), 0.4, 1e-6);
  EXPECT_TRUE(d["agnostic_nms"].get<bool>());
  EXPECT_TRUE(d["flip_test"].get<bool>());
  EXPECT_TRUE(nlohmann::json::parse(LastLine(fallback.out))["depth_smoothing"].get<bool>());
  const CommandResult set = RunMoslam("perceive " + seq +
                                      " --template-cache none --threshold 0.5 --nms 0.45 "
                                      "--per-class-nms --no-flip-test --no-depth-smoothing --json");
  ASSERT_EQ(set.exit_code, 0) << set.out;
  const auto e = nlohmann::json::parse(LastLine(set.out))["detector"];
  EXPECT_NEAR(e["threshold"].get<double>(), 0.5, 1e-6);
  EXPECT_NEAR(e["nms"].get<double>(), 0.45, 1e-6);
  EXPECT_FALSE(e["agnostic_nms"].get<bool>());
  EXPECT_FALSE(e["flip_test"].get<bool>());
  EXPECT_FALSE(nlohmann::json::parse(LastLine(set.out))["depth_smoothing"].get<bool>());
  const CommandResult bad = RunMoslam("perceive " + seq + " --nms 2");
  EXPECT_NE(bad.exit_code, 0) << bad.out;
  EXPECT_NE(bad.out.find("--nms"), std::string::npos) << bad.out;
  // An --out that cannot be written is refused before the frames are perceived.
  const CommandResult out =
      RunMoslam("perceive " + seq + " --out " + (dir / "no" / "x.json").string());
  EXPECT_EQ(out.exit_code, 1) << out.out;
  EXPECT_NE(out.out.find("moslam: error: perceive: --out '" + (dir / "no" / "x.json").string() +
                         "': no folder"),
            std::string::npos)
      << out.out;
  EXPECT_EQ(out.out.find("perceive: 1/1 frames"), std::string::npos) << out.out;
  fs::remove_all(dir);
}

TEST(CliExecutables, AMissingSiblingExecutableIsAClearError) {
  const fs::path dir = moslam::test::ScratchDir("alone");
  fs::create_directories(dir);
  const fs::path alone = dir / "moslam";
  fs::copy_file(MOSLAM_BINARY, alone, fs::copy_options::overwrite_existing);
  const CommandResult r = RunShell(alone.string() + " render --help");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find((dir / "moslam-perception").string()), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("could not be started"), std::string::npos) << r.out;
  fs::remove_all(dir);
}
