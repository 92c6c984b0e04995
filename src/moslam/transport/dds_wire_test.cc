// The receiving side of the DDS wire (dds_wire.h) without a domain: a taken sample whose
// sequences do not fit one another is refused by name before any packet is made of it.
#include "moslam/transport/dds_wire.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/throws_naming_testing.h"

namespace moslam::transport_detail {
namespace {

// A refinement coarse sample holding two coupling blocks, two pieces and two piece blocks (k = 2:
// blocks of 4 values; pieces of 3; piece blocks of 4), its sequences lent from the vectors here.
struct CoarseParts {
  std::vector<std::uint16_t> block_robots{1, 3};
  std::vector<double> blocks{1, 2, 3, 4, 5, 6, 7, 8};
  std::vector<std::uint32_t> piece_ids{0, 2};
  std::vector<double> piece_values{1, 2, 3, 4, 5, 6};
  std::vector<std::uint32_t> block_row_pieces{0, 2};
  std::vector<std::uint16_t> piece_block_robots{1, 1};
  std::vector<std::uint32_t> block_pieces{5, 6};
  std::vector<double> piece_block_values{1, 2, 3, 4, 5, 6, 7, 8};

  CoarseSample sample() {
    CoarseSample s{};
    s.sender = 0;
    s.stage = 3;
    s.kind = 5;
    s.k = 2;
    s.ncols = 1;
    Lend(block_robots, s.block_robots);
    Lend(blocks, s.blocks);
    Lend(piece_ids, s.piece_ids);
    Lend(piece_values, s.piece_values);
    Lend(block_row_pieces, s.block_row_pieces);
    Lend(piece_block_robots, s.piece_block_robots);
    Lend(block_pieces, s.block_pieces);
    Lend(piece_block_values, s.piece_block_values);
    return s;
  }
};

TEST(DdsWire, ACoarseSampleIsSplitIntoItsBlocksAndPieces) {
  CoarseParts parts;
  const CoarseMessage m = FromSample(parts.sample()).message;
  ASSERT_EQ(m.blocks.size(), 2u);
  EXPECT_EQ(m.blocks[1].first, 3);
  EXPECT_EQ(m.blocks[1].second, (std::vector<double>{5, 6, 7, 8}));
  ASSERT_EQ(m.pieces.size(), 2u);
  EXPECT_EQ(m.pieces[1].values, (std::vector<double>{4, 5, 6}));
  ASSERT_EQ(m.piece_blocks.size(), 2u);
  EXPECT_EQ(m.piece_blocks[1].row_piece, 2u);
  EXPECT_EQ(m.piece_blocks[1].piece, 6u);
  EXPECT_EQ(m.piece_blocks[1].values, (std::vector<double>{5, 6, 7, 8}));
}

TEST(DdsWire, ACoarseSampleWhoseSequencesDoNotFitIsRefusedNamingThem) {
  const std::vector<std::pair<std::string, std::function<void(CoarseParts&)>>> cases = {
      {"7 coupling values for 2 blocks", [](CoarseParts& p) { p.blocks.pop_back(); }},
      {"coupling values without blocks", [](CoarseParts& p) { p.block_robots.clear(); }},
      {"5 piece values for 2 pieces", [](CoarseParts& p) { p.piece_values.pop_back(); }},
      {"piece values without pieces", [](CoarseParts& p) { p.piece_ids.clear(); }},
      {"piece blocks of 2 robots, 1 row pieces and 2 pieces",
       [](CoarseParts& p) { p.block_row_pieces.pop_back(); }},
      {"piece blocks of 2 robots, 2 row pieces and 3 pieces",
       [](CoarseParts& p) { p.block_pieces.push_back(7); }},
      {"7 piece block values for 2 blocks",
       [](CoarseParts& p) { p.piece_block_values.pop_back(); }},
      {"piece block values without blocks",
       [](CoarseParts& p) {
         p.block_row_pieces.clear();
         p.piece_block_robots.clear();
         p.block_pieces.clear();
       }},
  };
  for (const auto& [why, spoil] : cases) {
    CoarseParts parts;
    spoil(parts);
    const CoarseSample s = parts.sample();
    EXPECT_TRUE(test::ThrowsNaming<InvalidInputError>([&] { FromSample(s); }, why)) << why;
  }
}

TEST(DdsWire, ACovarianceTriangleOfTheWrongSizeIsRefusedNamingIt) {
  std::vector<double> upper{4, 1, 0, 5, 2, 6};  // 3 x 3
  CovarianceSample s{};
  s.sender = 1;
  s.receiver = 0;
  s.dimension = 3;
  Lend(upper, s.upper);
  const Eigen::MatrixXd c = FromSample(s).message.covariance;
  ASSERT_EQ(c.rows(), 3);
  EXPECT_EQ(c(0, 1), 1.0);
  EXPECT_EQ(c(1, 0), 1.0);
  EXPECT_EQ(c(2, 2), 6.0);
  s.dimension = 4;
  EXPECT_TRUE(test::ThrowsNaming<InvalidInputError>([&] { FromSample(s); },
                                                    "covariance of dimension 4 with 6 entries"));
  // Beyond what the transport carries.
  s.dimension = kMaxTransportCovarianceDimension + 1;
  EXPECT_TRUE(test::ThrowsNaming<InvalidInputError>(
      [&] { FromSample(s); },
      "covariance of dimension " + std::to_string(kMaxTransportCovarianceDimension + 1)));
}

}  // namespace
}  // namespace moslam::transport_detail
