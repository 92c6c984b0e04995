// Test-only: whether a call is refused with an exception of type E (InvalidInputError unless
// said) whose message names what was wrong, for EXPECT_TRUE at the call site (so a failure points
// at the line that made it):
//   EXPECT_TRUE(ThrowsNaming([&] { MakeSyntheticGraph(o); }, "num_robots"));
#pragma once

#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "moslam/common/errors.h"

namespace moslam::test {

template <typename E = InvalidInputError, typename F>
::testing::AssertionResult ThrowsNaming(F&& call, const std::string& named) {
  try {
    call();
  } catch (const E& e) {
    if (std::string(e.what()).find(named) != std::string::npos) {
      return ::testing::AssertionSuccess();
    }
    return ::testing::AssertionFailure() << "the message does not name '" << named
                                         << "': " << e.what();
  }
  return ::testing::AssertionFailure() << "no exception (expected one naming '" << named << "')";
}

// Whether `base` validates and each change, applied alone to a copy of it, makes validate() throw
// an InvalidInputError naming the change's field (its first member):
//   EXPECT_TRUE(EachChangeIsRefused<C>({{"min_support", [](C& c) { c.min_support = 0; }}}));
template <typename Options>
::testing::AssertionResult EachChangeIsRefused(
    const std::vector<std::pair<std::string, std::function<void(Options&)>>>& changes,
    const Options& base = Options{}) {
  try {
    base.validate();
  } catch (const std::exception& e) {
    return ::testing::AssertionFailure() << "the unchanged options are refused: " << e.what();
  }
  for (const auto& [field, change] : changes) {
    Options changed = base;
    change(changed);
    const ::testing::AssertionResult r = ThrowsNaming([&] { changed.validate(); }, field);
    if (!r) return ::testing::AssertionFailure() << "changing " << field << ": " << r.message();
  }
  return ::testing::AssertionSuccess();
}

}  // namespace moslam::test
