// Test-only: whether a call is refused with an exception of type E (InvalidInputError unless
// said) whose message names what was wrong, for EXPECT_TRUE at the call site (so a failure points
// at the line that made it):
//   EXPECT_TRUE(ThrowsNaming([&] { MakeSyntheticGraph(o); }, "num_robots"));
#pragma once

#include <gtest/gtest.h>

#include <string>

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

}  // namespace moslam::test
