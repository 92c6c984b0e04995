#include "moslam/io/g2o.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/scratch_dir_testing.h"
#include "moslam/common/throws_naming_testing.h"

namespace moslam {
namespace {

namespace fs = std::filesystem;

const std::string kDatasets = MOSLAM_DATASETS_DIR;
const std::string kPgo = kDatasets + "/pgo/";
const std::string kDm =
    kDatasets + "/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/";

const std::string kIdentityInfo = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1";
const std::string kV0 = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n";
const std::string kV1 = "VERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n";
const std::string kE01 = "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1" + kIdentityInfo + "\n";

Dataset Parse(const std::string& text, const G2oReadOptions& options = {}) {
  std::istringstream in(text);
  return ParseG2o(in, "test.g2o", options);
}

// Parses `text`, expects a G2oParseError at `line` whose reason contains `needle`, and returns
// the reason.
std::string ExpectError(const std::string& text, int line, const std::string& needle) {
  try {
    Parse(text);
  } catch (const G2oParseError& e) {
    EXPECT_EQ(e.file(), "test.g2o");
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_NE(e.reason().find(needle), std::string::npos)
        << "reason '" << e.reason() << "' does not mention '" << needle << "'";
    const std::string expected_what = line > 0
                                          ? "test.g2o:" + std::to_string(line) + ": " + e.reason()
                                          : "test.g2o: " + e.reason();
    EXPECT_EQ(std::string(e.what()), expected_what);
    return e.reason();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected G2oParseError, got: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected G2oParseError for:\n" << text;
  return {};
}

std::string Edge(const std::string& ids, const std::string& info = kIdentityInfo) {
  return "EDGE_SE3:QUAT " + ids + " 1 0 0 0 0 0 1" + info + "\n";
}

// A scratch folder under the build tree, fresh for each test.
using test::ScratchDir;

bool BitEqual(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

template <typename Derived1, typename Derived2>
bool BitEqual(const Eigen::MatrixBase<Derived1>& a, const Eigen::MatrixBase<Derived2>& b) {
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    for (Eigen::Index j = 0; j < a.cols(); ++j) {
      if (!BitEqual(a(i, j), b(i, j))) return false;
    }
  }
  return true;
}

// Converting a rotation to a quaternion and back rounds: a few units in the last place.
constexpr double kQuaternionRoundingTol = 10 * std::numeric_limits<double>::epsilon();

SE3 RandomPose(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vector6 xi;
  for (int i = 0; i < 6; ++i) xi[i] = 3.0 * n(rng);
  return SE3::Exp(xi);
}

Matrix6 RandomInformation(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Matrix6 A;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) A(i, j) = u(rng);
  }
  Matrix6 info = A * A.transpose() + 0.1 * Matrix6::Identity();
  return 0.5 * (info + info.transpose());
}

// ---------------------------------------------------------------------------------------------
// Accepted input

TEST(G2oRead, ReadsVerticesEdgesAndNormalisesQuaternions) {
  const std::string text =
      "VERTEX_SE3:QUAT 0 1 2 3 0 0 0 2\n"  // non-unit identity quaternion
      "VERTEX_SE3:QUAT 1 4 5 6 0 0 0.70710678118654757 0.70710678118654757\n" +
      kE01;
  const Dataset d = Parse(text);
  ASSERT_EQ(d.initial.size(), 2u);
  ASSERT_EQ(d.graph.factors().size(), 1u);
  EXPECT_EQ(d.files, std::vector<std::string>{"test.g2o"});
  EXPECT_TRUE(d.plain_keys);
  const SE3& x0 = d.initial.at(Key::Pose(0, 0));
  EXPECT_TRUE(x0.rotation().matrix().isApprox(Matrix3::Identity(), 1e-15));
  EXPECT_EQ(x0.translation(), Vector3(1, 2, 3));
  const SE3& x1 = d.initial.at(Key::Pose(0, 1));
  Matrix3 rz90;
  rz90 << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_LT((x1.rotation().matrix() - rz90).cwiseAbs().maxCoeff(), 1e-15);
  const RelativePoseFactor& f = d.graph.factors()[0];
  EXPECT_EQ(f.a(), Key::Pose(0, 0));
  EXPECT_EQ(f.b(), Key::Pose(0, 1));
  EXPECT_EQ(f.measured().translation(), Vector3(1, 0, 0));
  EXPECT_EQ(f.information(), Matrix6::Identity());
}

TEST(G2oRead, PermutesInformationToRotationFirstWithoutRescaling) {
  // g2o order (x y z rx ry rz): diagonal 1..6, I14 = 0.5 couples x with rx, I26 = 0.25 y with rz.
  const std::string info = " 1 0 0 0.5 0 0  2 0 0 0 0.25  3 0 0 0  4 0 0  5 0  6";
  const Dataset d = Parse(kV0 + kV1 + Edge("0 1", info));
  const Matrix6& m = d.graph.factors().at(0).information();
  Matrix6 expected = Matrix6::Zero();
  expected.diagonal() << 4, 5, 6, 1, 2, 3;  // (rx ry rz x y z)
  expected(3, 0) = expected(0, 3) = 0.5;    // x-rx
  expected(4, 2) = expected(2, 4) = 0.25;   // y-rz
  EXPECT_EQ(m, expected);
}

TEST(G2oRead, AcceptsEdgeOnlyFiles) {
  const Dataset d = Parse(Edge("0 1") + Edge("1 2"));
  EXPECT_TRUE(d.initial.empty());
  EXPECT_EQ(d.graph.factors().size(), 2u);
  EXPECT_EQ(d.graph.keys().size(), 3u);
}

TEST(G2oRead, AcceptsEdgesWithIGreaterThanJ) {
  const Dataset d = Parse(kV0 + kV1 + Edge("1 0"));
  ASSERT_EQ(d.graph.factors().size(), 1u);
  EXPECT_EQ(d.graph.factors()[0].a(), Key::Pose(0, 1));
  EXPECT_EQ(d.graph.factors()[0].b(), Key::Pose(0, 0));
}

TEST(G2oRead, KeepsParallelEdges) {
  const Dataset d = Parse(kV0 + kV1 + kE01 + kE01 + Edge("1 0"));
  EXPECT_EQ(d.graph.factors().size(), 3u);
}

TEST(G2oRead, SkipsBlankLinesAndComments) {
  const std::string text = "# a comment\n\n   \t\n" + kV0 + "  # indented comment\n" +
                           "VERTEX_SE3:QUAT 1 1 0 0 0 0 0 1  # trailing comment\r\n" + "\n" + kE01 +
                           "\n";
  const Dataset d = Parse(text);
  EXPECT_EQ(d.initial.size(), 2u);
  EXPECT_EQ(d.graph.factors().size(), 1u);
}

TEST(G2oRead, DecodesSymbolKeysAndReportsPlainKeys) {
  const std::uint64_t a0 = (std::uint64_t{'a'} << 56) | 0;
  const std::uint64_t b7 = (std::uint64_t{'b'} << 56) | 7;
  const Dataset d = Parse("VERTEX_SE3:QUAT " + std::to_string(a0) + " 0 0 0 0 0 0 1\n" +
                          "VERTEX_SE3:QUAT " + std::to_string(b7) + " 0 0 0 0 0 0 1\n" +
                          Edge(std::to_string(a0) + " " + std::to_string(b7)));
  EXPECT_FALSE(d.plain_keys);
  EXPECT_EQ(d.initial.count(Key::Pose(0, 0)), 1u);
  EXPECT_EQ(d.initial.count(Key::Pose(1, 7)), 1u);
  EXPECT_TRUE(Parse(kV0 + kV1 + kE01).plain_keys);

  // Upper case: robots 26.. or objects, by scheme.
  const std::uint64_t C3 = (std::uint64_t{'C'} << 56) | 3;
  const std::string objects =
      kV0 + Edge("0 " + std::to_string(C3)) + Edge("0 " + std::to_string(C3));
  EXPECT_EQ(Parse(objects).graph.factors()[0].b(), Key::Pose(28, 3));
  EXPECT_EQ(Parse(objects, {KeyScheme::kWithObjects}).graph.factors()[0].b(), Key::Object(2, 3));
}

TEST(G2oRead, AcceptsAnEndpointWithoutVertexThatTwoEdgesConnect) {
  // Vertex 2 has no VERTEX line, but two edges reach it: not dangling.
  const Dataset d = Parse(kV0 + kV1 + kE01 + Edge("1 2") + Edge("2 0"));
  EXPECT_EQ(d.graph.factors().size(), 3u);
  EXPECT_EQ(d.initial.size(), 2u);
}

// ---------------------------------------------------------------------------------------------
// Rejected input: file, line and reason

TEST(G2oReject, NaN) {
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1 nan 0 0 0 0 0 1\n", 2, "NaN");
  ExpectError(kV0 + kV1 + Edge("0 1", " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 NaN 0 0 1 0 1"), 3, "NaN");
}

TEST(G2oReject, Inf) {
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1 0 -inf 0 0 0 0 1\n", 2, "Inf");
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1 0 0 1e999 0 0 0 1\n", 2, "out of the range");
}

TEST(G2oReject, TruncatedVertexLine) {
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1 0 0 0 0 0 0\n", 2, "needs 8 fields");
}

TEST(G2oReject, TruncatedEdgeLine) {
  const std::string truncated = "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0\n";
  const std::string reason = ExpectError(kV0 + kV1 + truncated, 3, "needs 30 fields");
  EXPECT_NE(reason.find("truncated"), std::string::npos);
}

TEST(G2oReject, TooManyFields) {
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1 0 0 0 0 0 0 1 7\n", 2, "too many fields");
}

TEST(G2oReject, NonNumber) {
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1 0 0 1.5abc 0 0 0 1\n", 2, "'1.5abc' is not a number");
  ExpectError(kV0 + kV1 + Edge("0 1", " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 x 0 0 1 0 1"), 3,
              "not a number");
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1 0x10 0 0 0 0 0 1\n", 2, "not a number");
}

TEST(G2oReject, InformationNotPositiveDefinite) {
  // Symmetric but indefinite: the x-y block [1 2; 2 1] has eigenvalue -1.
  ExpectError(kV0 + kV1 + Edge("0 1", " 1 2 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1"), 3,
              "not positive definite");
}

TEST(G2oReject, IndefiniteCouplingUnlessAskedToDropIt) {
  // Diagonal blocks SPD, z-rx coupling 5 makes the matrix indefinite.
  const std::string coupled = Edge("0 1", " 1 0 0 0 0 0 1 0 0 0 0 1 5 0 0 1 0 0 1 0 1");
  ExpectError(kV0 + kV1 + coupled, 3, "not positive definite");
  G2oReadOptions options;
  options.drop_indefinite_coupling = true;
  const Dataset d = Parse(kV0 + kV1 + coupled + kE01, options);
  EXPECT_EQ(d.repaired_information, 1);
  EXPECT_EQ(d.graph.factors().at(0).information(), Matrix6::Identity());
  EXPECT_EQ(d.graph.factors().at(1).information(), Matrix6::Identity());
  // A diagonal block that is not SPD is rejected all the same.
  std::istringstream bad(kV0 + kV1 + Edge("0 1", " 1 0 0 0 0 0 1 0 0 0 0 0 5 0 0 1 0 0 1 0 1"));
  EXPECT_THROW(ParseG2o(bad, "test.g2o", options), G2oParseError);
}

TEST(G2oRead, InformationNearDblMaxIsStoredFinite) {
  // SPD as read; symmetrising it as 0.5 * (I + I^T) used to overflow to Inf (found by the
  // fuzzer). The factor now keeps it finite, square root included.
  std::istringstream in(
      kV0 + kV1 + Edge("0 1", " 1e308 0 0 0 0 0 1e308 0 0 0 0 1e308 0 0 0 1e308 0 0 1e308 0 1e308"));
  const Dataset d = ParseG2o(in, "test.g2o");
  ASSERT_EQ(d.graph.factors().size(), 1u);
  EXPECT_TRUE(d.graph.factors()[0].information().allFinite());
  EXPECT_TRUE(d.graph.factors()[0].sqrtInformation().allFinite());
}

TEST(G2oReject, InformationWithZeroDiagonal) {
  // rz unmeasured (I66 = 0).
  ExpectError(kV0 + kV1 + Edge("0 1", " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 0"), 3,
              "not positive definite");
}

TEST(G2oReject, UnknownTag) {
  const std::string reason = ExpectError(kV0 + "VERTEX_XYZ 1 0 0 0\n", 2, "unknown tag");
  EXPECT_NE(reason.find("VERTEX_XYZ"), std::string::npos);
  ExpectError(kV0 + kV1 + kE01 + "EDGE_SE3_PRIOR 0 0 0 0 0 0 0 1\n", 4, "unknown tag");
  ExpectError(kV0 + "vertex_se3:quat 1 0 0 0 0 0 0 1\n", 2, "unknown tag");
}

TEST(G2oReject, FixIsAnUnknownTag) { ExpectError(kV0 + kV1 + kE01 + "FIX 0\n", 4, "FIX lines"); }

TEST(G2oReject, ATwoDimensionalLineInAThreeDimensionalFileOrTheReverse) {
  ExpectError(kV0 + "VERTEX_SE2 1 0 0 0\n", 2, "a 2D line in a file of 3D lines");
  ExpectError("VERTEX_SE2 0 0 0 0\n" + kE01, 2, "a 3D line in a file of 2D lines");
  ExpectError("VERTEX_SE2 0 0 0\n", 1, "needs 4 fields");
  ExpectError("EDGE_SE2 0 1 1 0 0 1 0 0 1 0\n", 1, "needs 11 fields");
  ExpectError("EDGE_SE2 0 1 1 0 0 1 0 0 -1 0 1\n", 1, "positive definite");
  ExpectError("EDGE_SE2 0 1 1 0 nan 1 0 0 1 0 1\n", 1, "theta");
}

// A 2D file reads as the planar SE(3) graph written out by hand: SE2 poses lifted to (Rz(theta),
// (x, y, 0)), the 3x3 information on (tx, ty, rz), rx and ry with theta's information and tz with
// the mean of x's and y's.
TEST(G2oPlanar, ATwoDimensionalFileIsItsLiftedGraph) {
  const Dataset d = Parse(
      "VERTEX_SE2 0 0 0 0\n"
      "VERTEX_SE2 1 1.5 -0.5 2.0\n"
      "EDGE_SE2 0 1 1.5 -0.5 2.0 40 1 2 50 3 600\n");
  EXPECT_TRUE(d.planar);
  EXPECT_TRUE(d.plain_keys);
  ASSERT_EQ(d.initial.size(), 2u);
  const SE3 x1(SO3::Exp(Vector3(0, 0, 2.0)), Vector3(1.5, -0.5, 0.0));
  EXPECT_TRUE(d.initial.at(Key::Pose(0, 1)).rotation().matrix().isApprox(x1.rotation().matrix(),
                                                                         1e-15));
  EXPECT_EQ(d.initial.at(Key::Pose(0, 1)).translation(), x1.translation());
  ASSERT_EQ(d.graph.factors().size(), 1u);
  const RelativePoseFactor& f = d.graph.factors()[0];
  EXPECT_TRUE(f.measured().rotation().matrix().isApprox(x1.rotation().matrix(), 1e-15));
  Matrix6 expected = Matrix6::Zero();  // rotation first: rx ry rz tx ty tz
  expected(3, 3) = 40;
  expected(3, 4) = expected(4, 3) = 1;
  expected(3, 2) = expected(2, 3) = 2;
  expected(4, 4) = 50;
  expected(4, 2) = expected(2, 4) = 3;
  expected(2, 2) = expected(0, 0) = expected(1, 1) = 600;
  expected(5, 5) = 45;
  EXPECT_EQ(f.information(), expected);
  EXPECT_FALSE(Parse(kV0 + kV1 + kE01).planar);
}

TEST(G2oPlanar, WritesTwoDimensionalLinesThatReadBackAndRefusesAPoseOffThePlane) {
  const std::string text =
      "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1.5 -0.5 2.0\nVERTEX_SE2 2 -3 0.25 -3.0\n"
      "EDGE_SE2 0 1 1.5 -0.5 2.0 40 1 2 50 3 600\nEDGE_SE2 1 2 0.1 0.2 -2.5 10 0 0 10 0 100\n";
  const Dataset d = Parse(text);
  G2oWriteOptions planar;
  planar.planar = true;
  planar.plain_keys = true;
  const fs::path path = ScratchDir() / "planar.g2o";
  WriteG2oFile(path.string(), d.graph, d.initial, planar);
  std::ifstream in(path);
  std::string first;
  in >> first;
  EXPECT_EQ(first, "VERTEX_SE2");
  const Dataset back = ReadG2oFile(path.string());
  EXPECT_TRUE(back.planar);
  ASSERT_EQ(back.initial.size(), d.initial.size());
  for (const auto& [key, x] : d.initial) {
    EXPECT_LT((back.initial.at(key).translation() - x.translation()).norm(), 1e-15);
    EXPECT_LT((back.initial.at(key).rotation().matrix() - x.rotation().matrix()).norm(), 1e-15);
  }
  ASSERT_EQ(back.graph.factors().size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(back.graph.factors()[i].information(), d.graph.factors()[i].information());
  }
  Values tilted = d.initial;
  tilted[Key::Pose(0, 2)] =
      tilted[Key::Pose(0, 2)] * SE3(SO3::Exp(Vector3(1e-6, 0, 0)), Vector3::Zero());
  EXPECT_THROW(WriteG2oFile(path.string(), d.graph, tilted, planar), InvalidInputError);
}

TEST(G2oReject, DanglingEdge) {
  // Vertex 5 is defined nowhere and only this edge reaches it.
  const std::string reason = ExpectError(kV0 + kV1 + kE01 + Edge("1 5"), 4, "dangling edge");
  EXPECT_NE(reason.find("id 5"), std::string::npos);
  EXPECT_NE(reason.find("no VERTEX_SE3:QUAT line"), std::string::npos) << reason;
  // A 2D file names its own vertex tag.
  const std::string planar = ExpectError(
      "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n"
      "EDGE_SE2 1 5 1 0 0 1 0 0 1 0 1\n",
      4, "dangling edge");
  EXPECT_NE(planar.find("no VERTEX_SE2 line"), std::string::npos) << planar;
}

TEST(G2oReject, EmptyFile) {
  ExpectError("", 0, "empty file");
  ExpectError("# only a comment\n\n  \n", 0, "empty file");
}

TEST(G2oReject, BinaryGarbage) {
  std::string garbage;
  std::mt19937 rng(7);
  for (int i = 0; i < 4096; ++i) garbage += static_cast<char>(rng() % 256);
  garbage[0] = '\x7f';  // not blank, not '#': the first token is garbage
  garbage[1] = '\x01';
  const std::string reason = ExpectError(garbage, 1, "unknown tag");
  EXPECT_NE(reason.find("\\x7f\\x01"), std::string::npos) << "non-printable bytes are escaped";
  ExpectError(std::string("\0\0\0\0", 4), 1, "unknown tag");
}

TEST(G2oReject, IdWhoseTopByteIsNotARobotLetter) {
  const std::uint64_t bad = (std::uint64_t{'#' + 1} << 56) | 3;  // '$'
  ExpectError(kV0 + "VERTEX_SE3:QUAT " + std::to_string(bad) + " 0 0 0 0 0 0 1\n", 2,
              "not a robot character");
  ExpectError(kV0 + Edge("0 18446744073709551615") + Edge("0 18446744073709551615"), 2,
              "not a robot character");
}

TEST(G2oReject, NegativeId) {
  ExpectError(kV0 + "VERTEX_SE3:QUAT -1 0 0 0 0 0 0 1\n", 2, "negative");
  ExpectError(kV0 + kV1 + Edge("0 -1"), 3, "negative");
}

TEST(G2oReject, IdAbove2To64) {
  ExpectError(kV0 + "VERTEX_SE3:QUAT 18446744073709551616 0 0 0 0 0 0 1\n", 2, "2^64");
}

TEST(G2oReject, NonIntegerId) {
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1.5 0 0 0 0 0 0 1\n", 2, "not an unsigned integer");
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1e3 0 0 0 0 0 0 1\n", 2, "not an unsigned integer");
}

TEST(G2oReject, DuplicateVertex) {
  const std::string reason =
      ExpectError(kV0 + kV1 + "VERTEX_SE3:QUAT 1 2 0 0 0 0 0 1\n", 3, "defined twice");
  EXPECT_NE(reason.find("test.g2o:2"), std::string::npos) << "names the first definition";
  // The plain id 4 and the Symbol a4 are the same variable.
  const std::uint64_t a4 = (std::uint64_t{'a'} << 56) | 4;
  ExpectError(
      "VERTEX_SE3:QUAT 4 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT " + std::to_string(a4) + " 0 0 0 0 0 0 1\n",
      2, "defined twice");
}

TEST(G2oReject, ZeroQuaternion) {
  ExpectError(kV0 + "VERTEX_SE3:QUAT 1 0 0 0 0 0 0 0\n", 2, "quaternion");
}

TEST(G2oReject, EdgeFromAVertexToItself) {
  ExpectError(kV0 + kV1 + Edge("1 1"), 3, "same variable");
}

TEST(G2oReject, MissingFileNamesThePath) {
  try {
    ReadG2oFile("/nonexistent/moslam/x.g2o");
    FAIL() << "expected G2oParseError";
  } catch (const G2oParseError& e) {
    EXPECT_EQ(e.file(), "/nonexistent/moslam/x.g2o");
    EXPECT_EQ(e.line(), 0);
    EXPECT_NE(e.reason().find("cannot open"), std::string::npos);
  }
}

// A folder given as a file and a file given as a folder: each reader says which it needs.
TEST(G2oReject, AFolderAsAFileAndAFileAsAFolder) {
  const fs::path dir = ScratchDir("folder_or_file");
  const fs::path file = dir / "one.g2o";
  std::ofstream(file) << kV0 + kV1 + kE01;
  EXPECT_TRUE(test::ThrowsNaming<G2oParseError>([&] { ReadG2oFile(dir.string()); },
                                                "is a folder, not a g2o file"));
  EXPECT_TRUE(test::ThrowsNaming<G2oParseError>([&] { ReadG2oFolder(file.string()); },
                                                "is not a folder of per-robot files"));
  EXPECT_EQ(ReadG2o(file.string()).graph.factors().size(), 1u);
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------------
// Writing

void ExpectSameFactors(const std::vector<RelativePoseFactor>& a,
                       const std::vector<RelativePoseFactor>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(a[k].a(), b[k].a()) << k;
    EXPECT_EQ(a[k].b(), b[k].b()) << k;
    EXPECT_TRUE(BitEqual(a[k].measured().translation(), b[k].measured().translation())) << k;
    EXPECT_LE((a[k].measured().rotation().matrix() - b[k].measured().rotation().matrix())
                  .cwiseAbs()
                  .maxCoeff(),
              kQuaternionRoundingTol)
        << k;
    EXPECT_TRUE(BitEqual(a[k].information(), b[k].information())) << k;
  }
}

void ExpectSameValues(const Values& a, const Values& b) {
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [key, x] : a) {
    ASSERT_EQ(b.count(key), 1u) << ToString(key);
    const SE3& y = b.at(key);
    EXPECT_TRUE(BitEqual(x.translation(), y.translation())) << ToString(key);
    EXPECT_LE((x.rotation().matrix() - y.rotation().matrix()).cwiseAbs().maxCoeff(),
              kQuaternionRoundingTol)
        << ToString(key);
  }
}

// Parses the quaternion (qx qy qz qw) of every VERTEX line, in file order.
std::vector<Eigen::Vector4d> WrittenQuaternions(const fs::path& path) {
  std::ifstream in(path);
  std::vector<Eigen::Vector4d> out;
  std::string tag, id;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    ls >> tag;
    if (tag != "VERTEX_SE3:QUAT") continue;
    std::string tok[8];
    for (auto& t : tok) ls >> t;
    Eigen::Vector4d q;
    for (int i = 0; i < 4; ++i) {
      const std::string& t = tok[4 + i];
      std::from_chars(t.data(), t.data() + t.size(), q[i]);
    }
    out.push_back(q);
  }
  return out;
}

TEST(G2oWrite, RoundTripIsBitExactUpToQuaternionRounding) {
  std::mt19937 rng(42);
  PoseGraph graph;
  Values values;
  for (std::uint64_t i = 0; i < 20; ++i) values[Key::Pose(0, i)] = RandomPose(rng);
  for (std::uint64_t i = 0; i < 5; ++i) values[Key::Pose(3, i)] = RandomPose(rng);
  values[Key::Pose(5, 0)] = SE3(SO3(), Vector3(-0.0, 1e-310, 1e300));  // -0, subnormal, huge
  for (std::uint64_t i = 0; i + 1 < 20; ++i) {
    graph.add(RelativePoseFactor(Key::Pose(0, i), Key::Pose(0, i + 1), RandomPose(rng),
                                 RandomInformation(rng)));
  }
  graph.add(RelativePoseFactor(Key::Pose(3, 4), Key::Pose(0, 2), RandomPose(rng),
                               RandomInformation(rng)));
  for (std::uint64_t i = 0; i + 1 < 5; ++i) {
    graph.add(RelativePoseFactor(Key::Pose(3, i), Key::Pose(3, i + 1), RandomPose(rng),
                                 RandomInformation(rng)));
  }
  const fs::path path = ScratchDir() / "graph.g2o";
  WriteG2oFile(path.string(), graph, values);
  const Dataset d = ReadG2oFile(path.string());
  EXPECT_FALSE(d.plain_keys);
  ExpectSameValues(values, d.initial);
  ExpectSameFactors(graph.factors(), d.graph.factors());

  // The quaternion is written to the last bit.
  const std::vector<Eigen::Vector4d> written = WrittenQuaternions(path);
  ASSERT_EQ(written.size(), values.size());
  std::size_t k = 0;
  for (const auto& entry : values) {
    const Eigen::Vector4d wxyz = entry.second.rotation().quaternionWxyz();
    EXPECT_TRUE(BitEqual(written[k], Eigen::Vector4d(wxyz[1], wxyz[2], wxyz[3], wxyz[0])));
    ++k;
  }

  EXPECT_EQ(d.graph.keys(), graph.keys());
}

TEST(G2oWrite, PlainKeysWriteRobotZeroAsIntegers) {
  PoseGraph graph;
  graph.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(0, 1), SE3(), Matrix6::Identity()));
  Values values{{Key::Pose(0, 0), SE3()}, {Key::Pose(0, 1), SE3()}};
  const fs::path path = ScratchDir() / "plain.g2o";
  WriteG2oFile(path.string(), graph, values, {KeyScheme::kPosesOnly, /*plain_keys=*/true});
  std::ifstream in(path);
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first.rfind("VERTEX_SE3:QUAT 0 ", 0), 0u) << first;
  const Dataset d = ReadG2oFile(path.string());
  EXPECT_TRUE(d.plain_keys);
  ExpectSameFactors(graph.factors(), d.graph.factors());

  WriteG2oFile(path.string(), graph, values);  // Symbol keys by default
  EXPECT_FALSE(ReadG2oFile(path.string()).plain_keys);
}

TEST(G2oWrite, ObjectsNeedTheObjectScheme) {
  PoseGraph graph;
  graph.add(RelativePoseFactor(Key::Pose(1, 0), Key::Object(1, 4), SE3(), Matrix6::Identity()));
  graph.add(RelativePoseFactor(Key::Pose(1, 1), Key::Object(1, 4), SE3(), Matrix6::Identity()));
  const fs::path path = ScratchDir() / "objects.g2o";
  EXPECT_THROW(WriteG2oFile(path.string(), graph, {}), InvalidInputError);
  WriteG2oFile(path.string(), graph, {}, {KeyScheme::kWithObjects, false});
  const Dataset d = ReadG2oFile(path.string(), {KeyScheme::kWithObjects});
  ExpectSameFactors(graph.factors(), d.graph.factors());
}

TEST(G2oWrite, FailureNamesThePath) {
  const std::string path = (ScratchDir() / "no_such_dir" / "x.g2o").string();
  EXPECT_TRUE(test::ThrowsNaming<Error>(
      [&] {
        WriteG2oFile(path, PoseGraph(), Values{{Key::Pose(0, 0), SE3()}});
      },
      path));
}

TEST(G2oWrite, AtomicWriteReplacesTheFileWholeAndLeavesNoTemporary) {
  const fs::path dir = ScratchDir() / "atomic";
  fs::create_directories(dir);
  const fs::path path = dir / "map.g2o";
  G2oWriteOptions atomic;
  atomic.atomic = true;
  const Values one{{Key::Pose(0, 0), SE3()}};
  const Values two{{Key::Pose(0, 0), SE3()}, {Key::Pose(0, 1), SE3()}};
  WriteG2oFile(path.string(), PoseGraph(), one, atomic);
  // A reader that opened the old file keeps reading the old file whole: the new one is another
  // file moved into place, not the old one truncated and written again.
  std::ifstream reader(path);
  WriteG2oFile(path.string(), PoseGraph(), two, atomic);
  std::stringstream old_text;
  old_text << reader.rdbuf();
  EXPECT_EQ(ParseG2o(old_text, "old").initial.size(), 1u);
  EXPECT_EQ(ReadG2oFile(path.string()).initial.size(), 2u);
  EXPECT_FALSE(fs::exists(path.string() + ".tmp"));
}

TEST(G2oWrite, AtomicWriteThatCannotRenameThrowsAndRemovesItsTemporary) {
  // A non-empty directory where the file should go: the text is written, the rename fails.
  const fs::path path = ScratchDir() / "atomic_over_dir.g2o";
  fs::create_directories(path / "inside");
  G2oWriteOptions atomic;
  atomic.atomic = true;
  EXPECT_TRUE(test::ThrowsNaming<Error>(
      [&] {
        WriteG2oFile(path.string(), PoseGraph(), Values{{Key::Pose(0, 0), SE3()}}, atomic);
      },
      "cannot move '" + path.string() + ".tmp' over '" + path.string() + "'"));
  EXPECT_FALSE(fs::exists(path.string() + ".tmp"));
  EXPECT_TRUE(fs::is_directory(path / "inside"));
}

TEST(G2oWrite, RefusesWhatItCannotWriteNamingIt) {
  const fs::path dir = ScratchDir("refusals");
  // An integer id carries 56 bits of index; a larger one is refused, not truncated.
  const Values big{{Key::Pose(0, kMaxKeyIndex + 1), SE3()}};
  EXPECT_TRUE(test::ThrowsNaming(
      [&] {
        WriteG2oFile((dir / "big.g2o").string(), PoseGraph(), big,
                     {KeyScheme::kPosesOnly, /*plain_keys=*/true});
      },
      "key index " + std::to_string(kMaxKeyIndex + 1) + " does not fit in 56 bits"));
  // A folder has a file per robot: a key of no robot has none.
  const Values negative{{Key::Pose(-1, 0), SE3()}};
  EXPECT_TRUE(
      test::ThrowsNaming([&] { WriteG2oFolder((dir / "team").string(), PoseGraph(), negative); },
                         "has a negative robot"));
  // An atomic write whose temporary cannot be written names it and leaves nothing behind.
  G2oWriteOptions atomic;
  atomic.atomic = true;
  const std::string path = (dir / "no_such_dir" / "map.g2o").string();
  EXPECT_TRUE(test::ThrowsNaming<Error>(
      [&] {
        WriteG2oFile(path, PoseGraph(), Values{{Key::Pose(0, 0), SE3()}}, atomic);
      },
      path + ".tmp"));
  EXPECT_FALSE(fs::exists(dir / "no_such_dir"));
}

// ---------------------------------------------------------------------------------------------
// Folders (distributed-mapper layout)

void WriteTextFile(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

std::string Id(int robot, int index) {
  return std::to_string((std::uint64_t(static_cast<unsigned char>(kRobotChars[robot])) << 56) |
                        std::uint64_t(index));
}
std::string Vertex(int robot, int index) {
  return "VERTEX_SE3:QUAT " + Id(robot, index) + " 0 0 0 0 0 0 1\n";
}

TEST(G2oFolder, CountsAnInterRobotEdgeOnceAndKeepsOneSidedOnes) {
  const fs::path dir = ScratchDir();
  const std::string shared = Edge(Id(0, 1) + " " + Id(1, 0));
  const std::string one_sided = Edge(Id(1, 1) + " " + Id(0, 0));
  WriteTextFile(dir / "0.g2o",
                Vertex(0, 0) + Vertex(0, 1) + Edge(Id(0, 0) + " " + Id(0, 1)) + shared);
  WriteTextFile(dir / "1.g2o",
                Vertex(1, 0) + Vertex(1, 1) + Edge(Id(1, 0) + " " + Id(1, 1)) + shared + one_sided);
  WriteTextFile(dir / "fullGraph.g2o", "garbage that must be ignored\n");
  const Dataset d = ReadG2oFolder(dir.string());
  EXPECT_EQ(d.initial.size(), 4u);
  EXPECT_EQ(d.graph.factors().size(), 4u);
  EXPECT_EQ(d.files,
            (std::vector<std::string>{(dir / "0.g2o").string(), (dir / "1.g2o").string()}));
  EXPECT_FALSE(d.plain_keys);
  EXPECT_EQ(ReadG2o(dir.string()).graph.factors().size(), 4u);
}

TEST(G2oFolder, RejectsAMissingIndex) {
  const fs::path dir = ScratchDir();
  WriteTextFile(dir / "0.g2o", Vertex(0, 0));
  WriteTextFile(dir / "2.g2o", Vertex(2, 0));
  try {
    ReadG2oFolder(dir.string());
    FAIL() << "expected G2oParseError";
  } catch (const G2oParseError& e) {
    EXPECT_NE(e.reason().find("missing 1.g2o"), std::string::npos) << e.what();
  }
}

TEST(G2oFolder, RejectsAFolderWithoutRobotFiles) {
  const fs::path dir = ScratchDir();
  WriteTextFile(dir / "fullGraph.g2o", kV0 + kV1 + kE01);
  try {
    ReadG2oFolder(dir.string());
    FAIL() << "expected G2oParseError";
  } catch (const G2oParseError& e) {
    EXPECT_NE(e.reason().find("0.g2o"), std::string::npos) << e.what();
  }
}

TEST(G2oFolder, DanglingRuleSpansTheFolder) {
  const fs::path dir = ScratchDir();
  // b0 is defined in 1.g2o: the edge a0-b0 in 0.g2o is fine. c9 is defined nowhere.
  WriteTextFile(dir / "0.g2o", Vertex(0, 0) + Edge(Id(0, 0) + " " + Id(1, 0)));
  WriteTextFile(dir / "1.g2o", Vertex(1, 0) + Edge(Id(1, 0) + " " + Id(2, 9)));
  try {
    ReadG2oFolder(dir.string());
    FAIL() << "expected G2oParseError";
  } catch (const G2oParseError& e) {
    EXPECT_EQ(e.file(), (dir / "1.g2o").string());
    EXPECT_EQ(e.line(), 2);
    EXPECT_NE(e.reason().find("dangling"), std::string::npos) << e.what();
    // Robot c (2) has no file in a folder of 0.g2o and 1.g2o: the likely cause is named.
    EXPECT_NE(e.reason().find("is 2.g2o missing?"), std::string::npos) << e.what();
  }
  // A robot whose file is there but defines no such pose: no file is missing.
  WriteTextFile(dir / "1.g2o", Vertex(1, 0) + Edge(Id(1, 0) + " " + Id(0, 9)));
  try {
    ReadG2oFolder(dir.string());
    FAIL() << "expected G2oParseError";
  } catch (const G2oParseError& e) {
    EXPECT_NE(e.reason().find("dangling"), std::string::npos) << e.what();
    EXPECT_EQ(e.reason().find("missing"), std::string::npos) << e.what();
  }
  WriteTextFile(dir / "1.g2o", Vertex(1, 0));
  EXPECT_EQ(ReadG2oFolder(dir.string()).graph.factors().size(), 1u);
}

// One dataset is 2D or 3D: a folder mixing them is refused, naming the odd file, either way round.
TEST(G2oFolder, RejectsA2DFileBesideA3DOne) {
  const fs::path dir = ScratchDir();
  const std::string planar = "VERTEX_SE2 " + Id(1, 0) + " 0 0 0\n";
  WriteTextFile(dir / "0.g2o", Vertex(0, 0));
  WriteTextFile(dir / "1.g2o", planar);
  try {
    ReadG2oFolder(dir.string());
    FAIL() << "expected G2oParseError";
  } catch (const G2oParseError& e) {
    EXPECT_EQ(e.file(), (dir / "1.g2o").string());
    EXPECT_NE(e.reason().find("a 2D file in a dataset whose first file is 3D"), std::string::npos)
        << e.what();
  }
  WriteTextFile(dir / "0.g2o", "VERTEX_SE2 " + Id(0, 0) + " 0 0 0\n");
  WriteTextFile(dir / "1.g2o", Vertex(1, 0));
  EXPECT_TRUE(test::ThrowsNaming<G2oParseError>([&] { ReadG2oFolder(dir.string()); },
                                                "a 3D file in a dataset whose first file is 2D"));
  WriteTextFile(dir / "1.g2o", planar);
  EXPECT_EQ(ReadG2oFolder(dir.string()).initial.size(), 2u);
}

TEST(G2oFolder, RejectsAVertexDefinedInTwoFiles) {
  const fs::path dir = ScratchDir();
  WriteTextFile(dir / "0.g2o", Vertex(0, 0) + Vertex(1, 0));
  WriteTextFile(dir / "1.g2o", "# robot 1\n" + Vertex(1, 0));
  try {
    ReadG2oFolder(dir.string());
    FAIL() << "expected G2oParseError";
  } catch (const G2oParseError& e) {
    EXPECT_EQ(e.file(), (dir / "1.g2o").string());
    EXPECT_EQ(e.line(), 2);
    EXPECT_NE(e.reason().find("defined twice"), std::string::npos) << e.what();
  }
}

// Factors as a sorted list (folder order groups by robot file).
std::vector<std::tuple<Key, Key, std::size_t>> SortedEnds(const PoseGraph& g) {
  std::vector<std::tuple<Key, Key, std::size_t>> out;
  for (std::size_t k = 0; k < g.factors().size(); ++k) {
    out.emplace_back(g.factors()[k].a(), g.factors()[k].b(), k);
  }
  std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) {
    if (std::get<0>(x) != std::get<0>(y)) return std::get<0>(x) < std::get<0>(y);
    return std::get<1>(x) < std::get<1>(y);
  });
  return out;
}

TEST(G2oFolder, WriteThenReadGivesTheSameGraph) {
  std::mt19937 rng(3);
  PoseGraph graph;
  Values values;
  const int robots = 3;
  for (int r = 0; r < robots; ++r) {
    for (std::uint64_t i = 0; i < 4; ++i) values[Key::Pose(r, i)] = RandomPose(rng);
    for (std::uint64_t i = 0; i + 1 < 4; ++i) {
      graph.add(RelativePoseFactor(Key::Pose(r, i), Key::Pose(r, i + 1), RandomPose(rng),
                                   RandomInformation(rng)));
    }
  }
  graph.add(RelativePoseFactor(Key::Pose(0, 3), Key::Pose(1, 0), RandomPose(rng),
                               RandomInformation(rng)));
  graph.add(RelativePoseFactor(Key::Pose(2, 1), Key::Pose(1, 2), RandomPose(rng),
                               RandomInformation(rng)));
  graph.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(2, 3), RandomPose(rng),
                               RandomInformation(rng)));
  const fs::path dir = ScratchDir() / "out";
  WriteG2oFolder(dir.string(), graph, values);
  ASSERT_TRUE(fs::exists(dir / "2.g2o"));
  EXPECT_FALSE(fs::exists(dir / "3.g2o"));
  const Dataset d = ReadG2oFolder(dir.string());
  ExpectSameValues(values, d.initial);
  const auto expected = SortedEnds(graph);
  const auto got = SortedEnds(d.graph);
  ASSERT_EQ(expected.size(), got.size());
  std::vector<RelativePoseFactor> a, b;
  for (std::size_t k = 0; k < got.size(); ++k) {
    a.push_back(graph.factors()[std::get<2>(expected[k])]);
    b.push_back(d.graph.factors()[std::get<2>(got[k])]);
  }
  ExpectSameFactors(a, b);
}

TEST(G2oFolder, WriteRefusesGapsAndStaleRobotFiles) {
  const fs::path dir = ScratchDir();
  PoseGraph graph;
  graph.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(2, 0), SE3(), Matrix6::Identity()));
  EXPECT_THROW(WriteG2oFolder(dir.string(), graph, {}), InvalidInputError);  // robot 1 empty

  PoseGraph two;
  two.add(RelativePoseFactor(Key::Pose(0, 0), Key::Pose(1, 0), SE3(), Matrix6::Identity()));
  WriteTextFile(dir / "5.g2o", kV0);
  try {
    WriteG2oFolder(dir.string(), two, {});
    FAIL() << "expected moslam::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("5.g2o"), std::string::npos) << e.what();
  }
}

// ---------------------------------------------------------------------------------------------
// The shared datasets

struct PgoFile {
  const char* name;
  std::size_t vertices;
  std::size_t edges;
};

TEST(G2oDatasets, ReadsEveryThreeDimensionalPgoFile) {
  // Counts from datasets/pgo/SOURCE.md.
  const PgoFile files[] = {
      {"sphere2500", 2500, 4949},
      {"torus3D", 5000, 9048},
      {"parking-garage", 1661, 6275},
      {"cubicle", 5750, 16869},
      {"smallGrid3D", 125, 297},
      {"tinyGrid3D", 9, 11},
      {"sphere_bignoise_vertex3", 2200, 8647},
  };
  for (const PgoFile& f : files) {
    SCOPED_TRACE(f.name);
    G2oReadOptions options;
    options.drop_indefinite_coupling = std::string(f.name) == "cubicle";
    const Dataset d = ReadG2o(kPgo + f.name + ".g2o", options);
    EXPECT_EQ(d.repaired_information, options.drop_indefinite_coupling ? 5021 : 0);
    EXPECT_EQ(d.initial.size(), f.vertices);
    EXPECT_EQ(d.graph.factors().size(), f.edges);
    EXPECT_EQ(d.graph.keys().size(), f.vertices);
    EXPECT_TRUE(d.plain_keys);
    EXPECT_EQ(d.graph.numRobots(), 1);
  }
}

TEST(G2oDatasets, CubicleHasIndefiniteInformationUnlessTheCouplingIsDropped) {
  // cubicle.g2o line 5753: x-y, z-rx and z-ry entries set; the z-rx-ry block
  // [10 84022.3 132748; 84022.3 10 0; 132748 0 10] is indefinite.
  try {
    ReadG2oFile(kPgo + "cubicle.g2o");
    FAIL() << "expected G2oParseError";
  } catch (const G2oParseError& e) {
    EXPECT_EQ(e.line(), 5753);
    EXPECT_NE(e.reason().find("not positive definite"), std::string::npos) << e.what();
    EXPECT_NE(e.reason().find("drop_indefinite_coupling"), std::string::npos) << e.what();
  }
  G2oReadOptions options;
  options.drop_indefinite_coupling = true;
  const Dataset d = ReadG2oFile(kPgo + "cubicle.g2o", options);
  // Line 5753 is the third edge (a parallel 1 -> 2): coupling gone, the rest as read.
  const Matrix6& info = d.graph.factors().at(2).information();
  EXPECT_EQ(Matrix3(info.topRightCorner<3, 3>()), Matrix3::Zero());
  EXPECT_EQ(info(3, 3), 2.46483e+06);
  EXPECT_EQ(info(3, 4), 5.3553e+06);
  EXPECT_EQ(info(5, 5), 10.0);
  EXPECT_EQ(info(2, 2), 91520.2);
}

TEST(G2oDatasets, TinyGrid3DFirstEdgeAsInTheFile) {
  // EDGE_SE3:QUAT 0 1 1.033099 0.093536 -0.037961 0.3171845 -0.2366641 0.1427899 0.9071908
  //               100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 25 0 0 25 0 25
  const Dataset d = ReadG2oFile(kPgo + "tinyGrid3D.g2o");
  const RelativePoseFactor& f = d.graph.factors().at(0);
  EXPECT_EQ(f.measured().translation(), Vector3(1.033099, 0.093536, -0.037961));
  const Eigen::Vector4d q = f.measured().rotation().quaternionWxyz();
  const double n = std::sqrt(0.3171845 * 0.3171845 + 0.2366641 * 0.2366641 + 0.1427899 * 0.1427899 +
                             0.9071908 * 0.9071908);
  EXPECT_NEAR(q[0], 0.9071908 / n, 1e-15);
  EXPECT_NEAR(q[1], 0.3171845 / n, 1e-15);
  EXPECT_NEAR(q[2], -0.2366641 / n, 1e-15);
  EXPECT_NEAR(q[3], 0.1427899 / n, 1e-15);
  Matrix6 expected = Matrix6::Zero();
  expected.diagonal() << 25, 25, 25, 100, 100, 100;
  EXPECT_EQ(f.information(), expected);
}

TEST(G2oDatasets, ReadsEveryTwoDimensionalPgoFile) {
  // Vertex lines, edge lines and distinct ids from datasets/pgo/SOURCE.md.
  struct Planar {
    const char* name;
    std::size_t vertices, edges, ids;
  };
  const Planar files[] = {
      {"intel", 1728, 2512, 1728},          {"manhattan", 0, 5453, 3500},
      {"city10000", 10000, 20687, 10000},   {"CSAIL", 0, 1172, 1045},
      {"MIT", 808, 827, 808},               {"ais2klinik", 15115, 16727, 15115},
      {"kitti_00", 0, 4677, 4541},          {"kitti_02", 0, 4703, 4661},
      {"kitti_05", 0, 2826, 2761},          {"kitti_06", 0, 1150, 1101},
      {"kitti_07", 0, 1106, 1101},          {"kitti_08", 0, 4070, 4071},
      {"kitti_09", 0, 1592, 1591},          {"input_INTEL_g2o", 1228, 1483, 1228},
      {"input_M3500_g2o", 3500, 5453, 3500},
  };
  for (const Planar& f : files) {
    SCOPED_TRACE(f.name);
    const Dataset d = ReadG2oFile(kPgo + f.name + ".g2o");
    EXPECT_TRUE(d.planar);
    EXPECT_EQ(d.initial.size(), f.vertices);
    EXPECT_EQ(d.graph.factors().size(), f.edges);
    EXPECT_EQ(d.graph.keys().size(), f.ids);
  }
}

struct DmFolder {
  const char* name;
  int robots;
  std::size_t vertices;
  std::size_t edges;  // distinct edges (= fullGraph.g2o edges where there is one)
};

// Counted with `cat k.g2o | grep ^EDGE | sort -u | wc -l` (separator edges appear twice).
const DmFolder kDmFolders[] = {
    {"blocks_world/2robots", 2, 64, 144},    {"blocks_world/4robots", 4, 64, 144},
    {"blocks_world/9robots", 9, 72, 156},    {"blocks_world/16robots", 16, 128, 288},
    {"blocks_world/25robots", 25, 200, 460}, {"blocks_world/36robots", 36, 288, 672},
    {"blocks_world/49robots", 49, 392, 924}, {"example_2robots", 2, 16, 28},
    {"example_4robots", 4, 64, 144},         {"example_9robots", 9, 72, 156},
    {"example_16robots", 16, 128, 288},      {"example_25robots", 25, 200, 460},
    {"example_36robots", 36, 288, 672},      {"example_49robots", 49, 392, 924},
};

TEST(G2oDatasets, ReadsEveryDistributedMapperFolder) {
  for (const DmFolder& f : kDmFolders) {
    SCOPED_TRACE(f.name);
    const Dataset d = ReadG2o(kDm + f.name);
    EXPECT_EQ(d.files.size(), static_cast<std::size_t>(f.robots));
    EXPECT_EQ(d.graph.numRobots(), f.robots);
    EXPECT_EQ(d.initial.size(), f.vertices);
    EXPECT_EQ(d.graph.factors().size(), f.edges);
    EXPECT_FALSE(d.plain_keys);
    std::size_t inter = 0;
    for (const RelativePoseFactor& factor : d.graph.factors()) {
      inter += factor.a().robot != factor.b().robot;
    }
    EXPECT_GT(inter, 0u);
  }
}

TEST(G2oDatasets, FoldersMatchTheirFullGraph) {
  for (const DmFolder& f : kDmFolders) {
    const fs::path full = fs::path(kDm) / f.name / "fullGraph.g2o";
    if (!fs::exists(full)) continue;
    SCOPED_TRACE(f.name);
    const Dataset folder = ReadG2oFolder(kDm + f.name);
    const Dataset whole = ReadG2oFile(full.string());
    EXPECT_TRUE(whole.plain_keys);
    EXPECT_EQ(folder.graph.factors().size(), whole.graph.factors().size());
    EXPECT_EQ(folder.initial.size(), whole.initial.size());
    // The plain key of fullGraph is the Symbol index of the per-robot key.
    const auto plain = [](const Key& k) { return Key::Pose(0, k.index); };
    for (const auto& [key, x] : folder.initial) {
      ASSERT_EQ(whole.initial.count(plain(key)), 1u) << ToString(key);
      EXPECT_TRUE(BitEqual(x.translation(), whole.initial.at(plain(key)).translation()));
    }
    std::multimap<std::pair<Key, Key>, Vector3> edges;
    for (const RelativePoseFactor& e : whole.graph.factors()) {
      edges.emplace(std::make_pair(e.a(), e.b()), e.measured().translation());
    }
    for (const RelativePoseFactor& e : folder.graph.factors()) {
      const auto range = edges.equal_range({plain(e.a()), plain(e.b())});
      const auto match = std::find_if(range.first, range.second, [&](const auto& entry) {
        return BitEqual(entry.second, e.measured().translation());
      });
      ASSERT_NE(match, range.second) << ToString(e.a()) << " " << ToString(e.b());
      edges.erase(match);
    }
    EXPECT_TRUE(edges.empty());
  }
}

}  // namespace
}  // namespace moslam
