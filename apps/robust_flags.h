// The flags of the robust solve that `moslam solve`, `moslam dgs`, `moslam robot` and `moslam team`
// share, and what they set.
#pragma once

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <algorithm>
#include <string>
#include <vector>

#include "cli.h"
#include "moslam/distributed/robust_dgs.h"

namespace moslam::cli {

struct RobustSolveArgs {
  std::string separator_test = "map";  // map | measurement
  double gnc_threshold = 0.0;          // 0: GncOptions' default
  int separator_support = 3;           // 0: no separator check
  bool retest_left_out = true;
  bool retest_groups = true;
  bool one_to_one_after_gnc = false;
  // The GNC threshold and the separator check (whether, its kind and support) in `options`.
  void applyTo(RobustDgsOptions* options) const {
    options->retest_left_out = retest_left_out;
    options->retest_groups = retest_groups;
    options->one_to_one_after_gnc = one_to_one_after_gnc;
    options->gnc.threshold = gnc_threshold;
    options->consistency.map_uncertainty = separator_test == "map";
    options->check_separators = separator_support > 0;
    options->consistency.min_support = std::max(1, separator_support);
  }
  // The same flags again, for a child process.
  std::vector<std::string> args() const {
    std::vector<std::string> a = {"--separator-test", separator_test, "--gnc-threshold",
                                  fmt::format("{}", gnc_threshold), "--separator-support",
                                  std::to_string(separator_support)};
    if (!retest_left_out) a.push_back("--no-retest-left-out");
    if (!retest_groups) a.push_back("--no-retest-groups");
    if (one_to_one_after_gnc) a.push_back("--one-to-one-after-gnc");
    return a;
  }
};

// --no-retest-left-out and --no-retest-groups (AddRobustSolveFlags adds them; `moslam simulate`
// alone).
inline void AddRetestFlags(CLI::App* sub, bool* retest, bool* groups) {
  sub->add_flag("!--no-retest-left-out", *retest,
                "--robust: do not test, after the inliers' solve, each separator the pairwise "
                "check left out that agrees with at least --separator-support kept ones of its "
                "robot pair against the joint estimate (one more solve each; it comes back when it "
                "raises the optimal cost by at most c2 / 2), nor the groups");
  sub->add_flag("!--no-retest-groups", *groups,
                "--robust: after that, do not test the separators of each robot pair the check "
                "left out as a group (all of them in, the truncated cost's weights to a fixed "
                "point: kept when the truncated cost falls)");
}

// --one-to-one-after-gnc (AddRobustSolveFlags adds it; `moslam simulate` alone).
inline void AddOneToOneFlag(CLI::App* sub, bool* one_to_one) {
  sub->add_flag("--one-to-one-after-gnc", *one_to_one,
                "--robust: keep the separator check's one-to-one rule after GNC too: no landmark "
                "stays paired with two landmarks of one robot (the smaller r^T Omega r wins)");
}

// --separator-test, --gnc-threshold, --separator-support and the re-test flags, written into
// `args` (which must outlive the parse).
inline void AddRobustSolveFlags(CLI::App* sub, RobustSolveArgs* args) {
  sub->add_option("--separator-test", args->separator_test,
                  "--robust: the pairwise check of the separators with each robot's map "
                  "uncertainty (map: marginal covariances, PCM's test) or with the separators' "
                  "information alone (measurement: when the information is not the noise's, "
                  "e.g. blocks_world's identity)")
      ->check(CLI::IsMember({"map", "measurement"}))
      ->capture_default_str();
  sub->add_option("--gnc-threshold", args->gnc_threshold,
                  "--robust: r^T Omega r beyond which a factor is an outlier (0: 22.46, chi-square "
                  "6 dof at 0.999, for information that is the noise's)")
      ->check(NonNegative())
      ->capture_default_str();
  sub->add_option("--separator-support", args->separator_support,
                  "--robust: before GNC, keep of each robot pair's separators (single robot: of "
                  "its loop closures) the largest pairwise consistent set if it has at least this "
                  "many (0: no check)")
      ->check(NonNegative())
      ->capture_default_str();
  AddRetestFlags(sub, &args->retest_left_out, &args->retest_groups);
  AddOneToOneFlag(sub, &args->one_to_one_after_gnc);
}

}  // namespace moslam::cli
