#include "robot_summaries.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "moslam/common/errors.h"

namespace moslam::cli {
namespace {

namespace fs = std::filesystem;

// The message of the InvalidInputError `f` throws ("" when it throws none).
template <class F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const InvalidInputError& e) {
    return e.what();
  }
  return "";
}

class TeamFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    out_ = fs::temp_directory_path() / ("moslam_summaries_test_" + std::to_string(::getpid()));
    fs::remove_all(out_);
  }
  void TearDown() override { fs::remove_all(out_); }
  void write(int robot, const std::string& text) {
    const fs::path dir = out_ / ("robot" + std::to_string(robot));
    fs::create_directories(dir);
    std::ofstream(dir / "summary.json") << text;
    std::ofstream(dir / "log.txt") << "robot " << robot << "\n";
  }
  fs::path out_;
};

TEST_F(TeamFolder, ReadsEveryFinishedRobotAndListsTheOthers) {
  write(0, R"({"pose_rounds": 7, "solves": [{"step": 3, "robots": [0, 2]}]})");
  write(2, R"({"pose_rounds": 9})");  // exited 1 (below): left out though it wrote a summary
  const TeamSummaries t = ReadTeamSummaries(out_, 3, {{2, 1}});
  EXPECT_FALSE(t.ok);
  ASSERT_EQ(t.summaries.size(), 1u);
  EXPECT_EQ(t.summaries.at(0).get<int>("pose_rounds"), 7);
  const std::vector<JsonFields> solves = t.summaries.at(0).items("solves");
  ASSERT_EQ(solves.size(), 1u);
  EXPECT_EQ(solves[0].get<std::vector<int>>("robots"), (std::vector<int>{0, 2}));
  ASSERT_EQ(t.failed.size(), 2u);
  // Robot 1 (no summary) was not run by this process: no exit code, and no log to point at.
  EXPECT_FALSE(t.failed.at(1).contains("exit_code")) << t.failed.at(1).dump();
  EXPECT_FALSE(t.failed.at(1).contains("log")) << t.failed.at(1).dump();
  EXPECT_EQ(t.failed.at(1)["reason"],
            "no " + (out_ / "robot1" / "summary.json").string() + " (it has not finished)");
  EXPECT_EQ(t.failed.at(2)["exit_code"], 1);
  EXPECT_EQ(t.failed.at(2)["reason"], "exit 1");
  EXPECT_NE(t.failed.at(2)["log"].get<std::string>().find("robot2"), std::string::npos);
}

TEST_F(TeamFolder, ARobotKilledAtTheTimeoutOrExitingZeroWithoutASummarySaysSo) {
  write(0, "{}");
  fs::create_directories(out_ / "robot1");
  const TeamSummaries t = ReadTeamSummaries(out_, 2, {{0, -1}, {1, 0}});
  EXPECT_FALSE(t.ok);
  ASSERT_EQ(t.failed.size(), 2u);
  EXPECT_EQ(t.failed.at(0)["reason"], "killed at the timeout");
  EXPECT_EQ(t.failed.at(1)["exit_code"], 0);
  EXPECT_EQ(t.failed.at(1)["reason"],
            "no " + (out_ / "robot1" / "summary.json").string() + " (it exited 0)");
}

TEST_F(TeamFolder, EveryRobotFinishedIsOk) {
  write(0, "{}");
  write(1, "{}");
  const TeamSummaries t = ReadTeamSummaries(out_, 2, {});
  EXPECT_TRUE(t.ok);
  EXPECT_TRUE(t.failed.empty());
  EXPECT_EQ(t.summaries.size(), 2u);
}

TEST_F(TeamFolder, ASummaryCutShortNamesItsFile) {
  write(0, R"({"pose_rounds": 7, "dds_estimate_bytes)");
  const std::string why = ErrorOf([&] { ReadTeamSummaries(out_, 1, {}); });
  EXPECT_NE(why.find("robot0/summary.json"), std::string::npos) << why;
  EXPECT_NE(why.find("not JSON"), std::string::npos) << why;
}

TEST(JsonFields, AMissingFieldIsNamedWithItsFile) {
  const JsonFields s = JsonFields::Parse(R"({"pose_rounds": 7})", "robot1/summary.json");
  const std::string why = ErrorOf([&] { s.get<int>("rotation_rounds"); });
  EXPECT_NE(why.find("robot1/summary.json"), std::string::npos) << why;
  EXPECT_NE(why.find("\"rotation_rounds\" is missing"), std::string::npos) << why;
}

TEST(JsonFields, AFieldOfAnotherTypeIsRefused) {
  const JsonFields s = JsonFields::Parse(R"({"pose_rounds": "seven", "solves": 3})", "f.json");
  EXPECT_NE(
      ErrorOf([&] { s.get<int>("pose_rounds"); }).find("field \"pose_rounds\" is not an integer"),
      std::string::npos);
  EXPECT_NE(ErrorOf([&] { s.items("solves"); }).find("field \"solves\" is not an array"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] {
              JsonFields::Parse("[1, 2]", "g.json").get<int>("x");
            }).find("a JSON object expected, found array"),
            std::string::npos);
}

TEST(JsonFields, AnIntegerOutOfItsTypesRangeOrNotWholeIsRefused) {
  const JsonFields s = JsonFields::Parse(
      R"({"big": 1e300, "half": 2.5, "wide": 4294967296, "negative": -1, "fine": 42})", "f.json");
  EXPECT_NE(ErrorOf([&] { s.get<int>("big"); }).find("not an integer within range"),
            std::string::npos);
  EXPECT_FALSE(ErrorOf([&] { s.get<std::int64_t>("half"); }).empty());
  EXPECT_FALSE(ErrorOf([&] { s.get<int>("wide"); }).empty());
  EXPECT_EQ(s.get<std::int64_t>("wide"), 4294967296);
  EXPECT_FALSE(ErrorOf([&] { s.get<std::uint64_t>("negative"); }).empty());
  EXPECT_EQ(s.get<int>("negative"), -1);
  EXPECT_EQ(s.get<int>("fine"), 42);
  EXPECT_DOUBLE_EQ(s.get<double>("fine"), 42.0);
  const std::string why = ErrorOf([&] {
    JsonFields::Parse(R"({"robots": [0, "one"]})", "f.json").get<std::vector<int>>("robots");
  });
  EXPECT_NE(why.find("field \"robots\"[1] is not an integer"), std::string::npos) << why;
}

TEST(JsonFields, AnArrayElementIsNamedByItsIndex) {
  const JsonFields s =
      JsonFields::Parse(R"({"rendezvous": [{"alpha": 0}, {"beta": 1}]})", "robot2/summary.json");
  const std::vector<JsonFields> events = s.items("rendezvous");
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].get<int>("alpha"), 0);
  const std::string why = ErrorOf([&] { events[1].get<int>("alpha"); });
  EXPECT_NE(why.find("robot2/summary.json: rendezvous[1]: field \"alpha\" is missing"),
            std::string::npos)
      << why;
  EXPECT_NE(ErrorOf([&] { events[0].as<std::vector<int>>(); }).find("the value is not an array"),
            std::string::npos);
}

TEST(JsonFields, AnOptionalArrayMayBeAbsent) {
  const JsonFields s = JsonFields::Parse("{}", "f.json");
  EXPECT_TRUE(s.items("set_aside", /*optional=*/true).empty());
  EXPECT_FALSE(ErrorOf([&] { s.items("set_aside"); }).empty());
}

}  // namespace
}  // namespace moslam::cli
