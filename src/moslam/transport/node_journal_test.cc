#include "moslam/transport/node_journal.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <string>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"

namespace moslam::transport_detail {
namespace {

TeamStep StepWith(double change) {
  TeamStep step;
  TeamReport report;
  report.sent = true;
  report.change = change;
  step.reports[0] = report;
  step.reports[1] = report;
  return step;
}

TEST(NodeJournal, ARestartReplaysStepsDeparturesAndTheEndInOrder) {
  const std::filesystem::path dir = test::ScratchDir();
  const std::string path = (dir / "journal.bin").string();
  {
    NodeJournal first(path, 1, 42, dir.string());
    EXPECT_EQ(first.starts(), 0);
    EXPECT_TRUE(first.team().empty());
    EXPECT_FALSE(first.replaying());
    first.recordStart();
    first.recordTeam({0, 1, 2});
    first.recordStep(1, DgsStage::kRotation, StepWith(0.5));
    first.recordLeft(2, 1);
    first.recordStep(2, DgsStage::kPose, StepWith(0.25));
    first.recordDone();
  }
  NodeJournal again(path, 1, 42, dir.string());
  EXPECT_EQ(again.starts(), 1);
  EXPECT_EQ(again.team(), (std::set<int>{0, 1, 2}));
  EXPECT_TRUE(again.replaying());
  std::set<int> left;
  bool done = false;
  const std::optional<TeamStep> one = again.replay(1, DgsStage::kRotation, left, done);
  ASSERT_TRUE(one.has_value());
  EXPECT_EQ(one->reports.at(1).change, 0.5);
  EXPECT_TRUE(left.empty());  // robot 2 left after step 1
  const std::optional<TeamStep> two = again.replay(2, DgsStage::kPose, left, done);
  ASSERT_TRUE(two.has_value());
  EXPECT_EQ(two->reports.at(0).change, 0.25);
  EXPECT_EQ(left, (std::set<int>{2}));
  EXPECT_FALSE(done);
  EXPECT_FALSE(again.replay(3, DgsStage::kPose, left, done).has_value());
  EXPECT_TRUE(done);
  EXPECT_FALSE(again.replaying());
}

TEST(NodeJournal, AnotherRunsJournalOrAStepOutOfOrderIsRefused) {
  const std::filesystem::path dir = test::ScratchDir();
  const std::string path = (dir / "journal.bin").string();
  {
    NodeJournal first(path, 1, 42, dir.string());
    first.recordStep(1, DgsStage::kRotation, StepWith(0.5));
  }
  for (const auto& [robot, fingerprint] : {std::pair{1, 43ull}, std::pair{2, 42ull}}) {
    EXPECT_TRUE(test::ThrowsNaming(
        [&, robot = robot, fingerprint = fingerprint] {
          NodeJournal other(path, robot, fingerprint, "the/state/dir");
        },
        "the/state/dir holds the journal of another run"))
        << "robot " << robot << " run " << fingerprint;
  }
  NodeJournal again(path, 1, 42, dir.string());
  std::set<int> left;
  bool done = false;
  EXPECT_THROW(again.replay(2, DgsStage::kRotation, left, done), InvalidInputError);
}

}  // namespace
}  // namespace moslam::transport_detail
