// Runs the real `moslam` binary: bad input must exit non-zero with file and line, never crash;
// --json must end with one JSON object carrying the documented fields.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

namespace {

namespace fs = std::filesystem;

struct CommandResult {
  int exit_code;
  std::string out;  // stdout and stderr, interleaved
};

CommandResult RunMoslam(const std::string& args) {
  const std::string cmd = std::string(MOSLAM_BINARY) + " " + args + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return {-1, "popen failed"};
  std::string out;
  std::array<char, 4096> buf;
  while (size_t n = fread(buf.data(), 1, buf.size(), pipe)) out.append(buf.data(), n);
  const int status = pclose(pipe);
  // A crash (signal) is reported as a distinct code so the tests can tell it from exit 1.
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), out};
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
  const fs::path file = fs::temp_directory_path() / (std::string("moslam_cli_") + name + ".g2o");
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

TEST(Cli, UsageErrorsAndMissingFiles) {
  EXPECT_NE(RunMoslam("solve").exit_code, 0);
  EXPECT_NE(RunMoslam("solve x.g2o --method newton").exit_code, 0);
  const CommandResult missing = RunMoslam("solve /nonexistent/file.g2o");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.out.find("/nonexistent/file.g2o"), std::string::npos);
  // An edge-only file has nothing for --init file, but solves from odometry or chordal.
  const fs::path edges = fs::temp_directory_path() / "moslam_cli_edges_only.g2o";
  std::ofstream(edges) << Edge("0 1") << Edge("1 2") << Edge("2 0");
  const CommandResult no_vertices = RunMoslam("solve " + edges.string() + " --init file");
  EXPECT_EQ(no_vertices.exit_code, 1);
  EXPECT_NE(no_vertices.out.find("--init chordal"), std::string::npos) << no_vertices.out;
  EXPECT_EQ(RunMoslam("solve " + edges.string() + " --init odometry").exit_code, 0);
  fs::remove(edges);
}

TEST(Cli, WritesG2oAndTumThatReadBack) {
  const fs::path dir = fs::temp_directory_path() / "moslam_cli_out";
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

}  // namespace
