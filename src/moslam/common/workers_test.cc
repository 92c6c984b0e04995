#include "moslam/common/workers.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace moslam {
namespace {

TEST(ForEachOnWorkers, RunsEveryIndexOnceOnItsWorker) {
  for (const std::size_t workers : {0, 1, 2, 3, 8}) {
    const std::size_t n = 7;
    std::vector<int> calls(n, 0);
    std::vector<std::thread::id> ran_on(n);
    ForEachOnWorkers(n, workers, [&](std::size_t i) {
      ++calls[i];  // one writer per index: no lock
      ran_on[i] = std::this_thread::get_id();
    });
    for (std::size_t i = 0; i < n; ++i) EXPECT_EQ(calls[i], 1) << workers << " workers, " << i;
    if (workers <= 1) {
      for (std::size_t i = 0; i < n; ++i) EXPECT_EQ(ran_on[i], std::this_thread::get_id());
    } else {
      const std::size_t used = std::min(workers, n);
      for (std::size_t i = 0; i < n; ++i) {
        EXPECT_NE(ran_on[i], std::this_thread::get_id()) << i;
        EXPECT_EQ(ran_on[i], ran_on[i % used]) << workers << " workers, " << i;
        if (i < used && i > 0) EXPECT_NE(ran_on[i], ran_on[0]) << i;
      }
    }
  }
  ForEachOnWorkers(0, 2, [](std::size_t) { FAIL() << "no index to run"; });
}

TEST(ForEachOnWorkers, RethrowsTheLowestWorkersExceptionOnceAllHaveJoined) {
  const std::size_t n = 9, workers = 3;
  std::vector<int> ran(n, 0);
  try {
    ForEachOnWorkers(n, workers, [&](std::size_t i) {
      // Worker 1 throws at its first index (1), worker 2 at its second (5): worker 1's reaches us.
      if (i == 1 || i == 5) throw std::runtime_error("index " + std::to_string(i));
      ran[i] = 1;
    });
    FAIL() << "no throw";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "index 1");
  }
  // Worker 0 ran all of its indices; worker 1 none after its throw; worker 2 those before its.
  EXPECT_EQ(ran, (std::vector<int>{1, 0, 1, 1, 0, 0, 1, 0, 0}));
}

TEST(ForEachOnWorkers, OnTheCallingThreadTheFirstExceptionStopsTheRest) {
  int last = -1;
  EXPECT_THROW(ForEachOnWorkers(5, 1,
                                [&](std::size_t i) {
                                  if (i == 2) throw std::invalid_argument("stop");
                                  last = static_cast<int>(i);
                                }),
               std::invalid_argument);
  EXPECT_EQ(last, 1);
}

}  // namespace
}  // namespace moslam
