#include "moslam/io/g2o.h"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <istream>
#include <limits>
#include <locale>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <system_error>
#include <tuple>
#include <unordered_map>
#include <utility>

#include "moslam/common/number_text.h"
#include "moslam/common/whole_file.h"

namespace moslam {
namespace {

namespace fs = std::filesystem;

constexpr std::string_view kVertexTag = "VERTEX_SE3:QUAT";
constexpr std::string_view kEdgeTag = "EDGE_SE3:QUAT";
constexpr std::size_t kVertexFields = 8;      // id x y z qx qy qz qw
constexpr std::size_t kEdgeFields = 9 + 21;   // i j x y z qx qy qz qw + upper triangle
constexpr std::size_t kEdgeNumbers = 7 + 21;  // the doubles of an edge line
// 2D files, read as planar SE(3) graphs (Dataset::planar).
constexpr std::string_view kVertex2Tag = "VERTEX_SE2";
constexpr std::string_view kEdge2Tag = "EDGE_SE2";
constexpr std::size_t kVertex2Fields = 4;      // id x y theta
constexpr std::size_t kEdge2Fields = 5 + 6;    // i j x y theta + upper triangle of (x, y, theta)

// g2o orders a tangent vector (x, y, z, rx, ry, rz); moslam (rx, ry, rz, x, y, z).
constexpr int MoslamIndex(int g2o_index) { return (g2o_index + 3) % 6; }

std::string FormatError(const std::string& file, int line, const std::string& reason) {
  if (line <= 0) return file + ": " + reason;
  return file + ":" + std::to_string(line) + ": " + reason;
}

// A token as it may be printed in a message: at most 40 characters, non-printable bytes escaped
// (binary input must give a readable message).
std::string Printable(std::string_view token) {
  constexpr std::size_t kMax = 40;
  std::string out;
  for (std::size_t i = 0; i < token.size() && i < kMax; ++i) {
    const auto c = static_cast<unsigned char>(token[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 0xf];
    }
  }
  if (token.size() > kMax) out += "...";
  return out;
}

// Splits on blanks; '#' starts a comment that runs to the end of the line.
std::vector<std::string_view> Tokenize(std::string_view line) {
  const auto hash = line.find('#');
  if (hash != std::string_view::npos) line = line.substr(0, hash);
  static constexpr std::string_view kBlanks = " \t\r\v\f";
  std::vector<std::string_view> tokens;
  std::size_t pos = 0;
  while (true) {
    pos = line.find_first_not_of(kBlanks, pos);
    if (pos == std::string_view::npos) break;
    std::size_t end = line.find_first_of(kBlanks, pos);
    if (end == std::string_view::npos) end = line.size();
    tokens.push_back(line.substr(pos, end - pos));
    pos = end;
  }
  return tokens;
}

// Where a line of the dataset came from.
struct Location {
  const std::string* file;
  int line;
};

[[noreturn]] void Fail(const Location& at, const std::string& reason) {
  throw G2oParseError(*at.file, at.line, reason);
}

// A whole token as a finite double (locale-independent; "1.5abc", hex, NaN and Inf rejected).
double ParseNumber(std::string_view token, const char* what, const Location& at) {
  double value = 0.0;
  const NumberStatus status = ParseNumberToken(token, value);
  if (status != NumberStatus::kOk) {
    Fail(at, std::string(what) + " '" + Printable(token) + "' " + NumberStatusReason(status, "a double"));
  }
  return value;
}

// A whole token as an unsigned 64-bit id.
std::uint64_t ParseId(std::string_view token, const Location& at) {
  std::uint64_t value = 0;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  if (!token.empty() && token[0] == '-') {
    Fail(at, "id '" + Printable(token) + "' is negative: ids are unsigned 64-bit Symbol keys");
  }
  if (ec == std::errc::result_out_of_range) {
    Fail(at, "id '" + Printable(token) + "' is out of range: larger than 2^64 - 1");
  }
  if (ec != std::errc() || ptr != end) {
    Fail(at, "id '" + Printable(token) + "' is not an unsigned integer");
  }
  return value;
}

struct DecodedId {
  std::uint64_t raw;
  Key key;
};

DecodedId Decode(std::string_view token, const G2oReadOptions& options, const Location& at) {
  const std::uint64_t raw = ParseId(token, at);
  try {
    return {raw, DecodeSymbol(raw, options.scheme)};
  } catch (const InvalidInputError& e) {
    Fail(at, e.what());
  }
}

// x y z qx qy qz qw (7 tokens) as a pose; the quaternion is normalised, a zero one rejected.
SE3 ParsePose(const std::vector<std::string_view>& tokens, std::size_t first,
              std::array<double, 7>* numbers, const Location& at) {
  static constexpr const char* kNames[7] = {"x", "y", "z", "qx", "qy", "qz", "qw"};
  std::array<double, 7>& v = *numbers;
  for (std::size_t i = 0; i < 7; ++i) v[i] = ParseNumber(tokens[first + i], kNames[i], at);
  if (v[3] == 0.0 && v[4] == 0.0 && v[5] == 0.0 && v[6] == 0.0) {
    Fail(at, "quaternion (qx qy qz qw) is zero: it encodes no rotation");
  }
  try {  // any finite non-zero norm is normalised, without overflow or underflow
    return SE3(SO3::FromQuaternion(v[6], v[3], v[4], v[5]), Vector3(v[0], v[1], v[2]));
  } catch (const std::invalid_argument& e) {
    Fail(at, std::string("quaternion (qx qy qz qw) cannot be normalised: ") + e.what());
  }
}

struct VertexRecord {
  DecodedId id;
  SE3 pose;
  Location at;
};

struct EdgeRecord {
  DecodedId a, b;
  std::array<double, kEdgeNumbers> numbers;  // as read: for recognising the copy of an edge
  Location at;
  bool repaired;  // read with drop_indefinite_coupling
};

struct FileRecords {
  std::vector<VertexRecord> vertices;
  std::vector<EdgeRecord> edges;
  std::vector<RelativePoseFactor> factors;  // one per edge, in the same order
  bool plain_keys = true;
  int dimension = 0;  // 2 or 3 after the first vertex or edge line; a file holds one kind
};

// Records that the line at `at` is of a `dimension`-D tag; a file mixing 2D and 3D lines fails.
void NoteDimension(int dimension, const Location& at, FileRecords* out) {
  if (out->dimension == 0) out->dimension = dimension;
  if (out->dimension != dimension) {
    Fail(at, "a " + std::to_string(dimension) + "D line in a file of " +
                 std::to_string(out->dimension) +
                 "D lines: a file holds SE2 or SE3:QUAT lines, not both");
  }
}

void CheckFieldCount(const std::vector<std::string_view>& tokens, std::size_t expected,
                     const char* layout, const Location& at) {
  const std::size_t found = tokens.size() - 1;
  if (found == expected) return;
  Fail(at, std::string(tokens[0]) + " needs " + std::to_string(expected) +
               " fields after the tag (" + layout + "), found " + std::to_string(found) +
               (found < expected ? " (truncated line?)" : " (too many fields)"));
}

[[noreturn]] void FailTag(std::string_view tag, const Location& at) {
  const std::string shown = "'" + Printable(tag) + "'";
  if (tag == "FIX") {
    Fail(at, "unknown tag " + shown +
                 ": moslam does not read FIX lines (the gauge is always the first pose of "
                 "robot 0); remove the line");
  }
  Fail(at, "unknown tag " + shown +
               ": moslam reads VERTEX_SE3:QUAT and EDGE_SE3:QUAT lines, or VERTEX_SE2 and "
               "EDGE_SE2 lines");
}

// x y theta (3 tokens) as the planar pose (Rz(theta), (x, y, 0)).
SE3 ParsePlanarPose(const std::vector<std::string_view>& tokens, std::size_t first,
                    std::array<double, 3>* numbers, const Location& at) {
  static constexpr const char* kNames[3] = {"x", "y", "theta"};
  std::array<double, 3>& v = *numbers;
  for (std::size_t i = 0; i < 3; ++i) v[i] = ParseNumber(tokens[first + i], kNames[i], at);
  return SE3(SO3::Exp(Vector3(0.0, 0.0, v[2])), Vector3(v[0], v[1], 0.0));
}

// A VERTEX_SE3:QUAT (dimension 3) or VERTEX_SE2 (2) line.
void ParseVertex(const std::vector<std::string_view>& tokens, int dimension,
                 const G2oReadOptions& options, const Location& at, FileRecords* out) {
  const bool planar = dimension == 2;
  CheckFieldCount(tokens, planar ? kVertex2Fields : kVertexFields,
                  planar ? "id x y theta" : "id x y z qx qy qz qw", at);
  NoteDimension(dimension, at, out);
  const DecodedId id = Decode(tokens[1], options, at);
  std::array<double, 7> numbers{};
  std::array<double, 3> planar_numbers{};
  const SE3 pose = planar ? ParsePlanarPose(tokens, 2, &planar_numbers, at)
                          : ParsePose(tokens, 2, &numbers, at);
  out->plain_keys = out->plain_keys && (id.raw >> 56) == 0;
  out->vertices.push_back({id, pose, at});
}

// An SE2 edge as a planar SE(3) factor: its 3x3 information on (x, y, theta) goes to (tx, ty, rz);
// the out-of-plane directions, which a planar graph never moves along (a reflection z -> -z maps
// the problem onto itself, so its gradient there is zero at every planar estimate), get the
// information of their in-plane counterparts (rx, ry: theta's; tz: the mean of x's and y's), so
// that the lifted system is as well conditioned as the planar one.
void ParseEdge2(const std::vector<std::string_view>& tokens, const G2oReadOptions& options,
                const Location& at, FileRecords* out) {
  CheckFieldCount(tokens, kEdge2Fields,
                  "i j x y theta and the 6 upper-triangular information entries", at);
  NoteDimension(2, at, out);
  const DecodedId a = Decode(tokens[1], options, at);
  const DecodedId b = Decode(tokens[2], options, at);
  std::array<double, 3> pose_numbers{};
  const SE3 measured = ParsePlanarPose(tokens, 3, &pose_numbers, at);
  std::array<double, kEdgeNumbers> numbers{};
  std::copy(pose_numbers.begin(), pose_numbers.end(), numbers.begin());
  static constexpr const char* kEntryNames[6] = {
      "information entry I11", "information entry I12", "information entry I13",
      "information entry I22", "information entry I23", "information entry I33"};
  static constexpr int kMoslam[3] = {3, 4, 2};  // x, y, theta -> tx, ty, rz (rotation first)
  Matrix6 information = Matrix6::Zero();
  std::size_t k = 0;
  for (int i = 0; i < 3; ++i) {
    for (int j = i; j < 3; ++j, ++k) {
      const double v = ParseNumber(tokens[6 + k], kEntryNames[k], at);
      numbers[3 + k] = v;
      information(kMoslam[i], kMoslam[j]) = v;
      information(kMoslam[j], kMoslam[i]) = v;
    }
  }
  information(0, 0) = information(1, 1) = information(2, 2);
  information(5, 5) = 0.5 * (information(3, 3) + information(4, 4));
  try {
    out->factors.emplace_back(a.key, b.key, measured, information);
  } catch (const InvalidInputError& e) {
    Fail(at, std::string("edge ") + std::to_string(a.raw) + " " + std::to_string(b.raw) + ": " +
                 e.what());
  }
  out->plain_keys = out->plain_keys && (a.raw >> 56) == 0 && (b.raw >> 56) == 0;
  out->edges.push_back({a, b, numbers, at, false});
}

void ParseEdge(const std::vector<std::string_view>& tokens, const G2oReadOptions& options,
               const Location& at, FileRecords* out) {
  CheckFieldCount(tokens, kEdgeFields,
                  "i j x y z qx qy qz qw and the 21 upper-triangular information entries", at);
  NoteDimension(3, at, out);
  const DecodedId a = Decode(tokens[1], options, at);
  const DecodedId b = Decode(tokens[2], options, at);
  std::array<double, kEdgeNumbers> numbers{};
  std::array<double, 7> pose_numbers{};
  const SE3 measured = ParsePose(tokens, 3, &pose_numbers, at);
  std::copy(pose_numbers.begin(), pose_numbers.end(), numbers.begin());
  // The entries' names for error messages, I11 .. I66 in file order.
  static const std::array<std::string, 21> kEntryNames = [] {
    std::array<std::string, 21> names;
    std::size_t n = 0;
    for (int i = 1; i <= 6; ++i) {
      for (int j = i; j <= 6; ++j) names[n++] = "information entry I" + std::to_string(10 * i + j);
    }
    return names;
  }();
  Matrix6 information;
  std::size_t k = 7;
  for (int i = 0; i < 6; ++i) {
    for (int j = i; j < 6; ++j, ++k) {
      numbers[k] = ParseNumber(tokens[3 + k], kEntryNames[k - 7].c_str(), at);
      information(MoslamIndex(i), MoslamIndex(j)) = numbers[k];
      information(MoslamIndex(j), MoslamIndex(i)) = numbers[k];
    }
  }
  const auto make_factor = [&](const Matrix6& info) {
    return RelativePoseFactor(a.key, b.key, measured, info);
  };
  bool repaired = false;
  std::optional<RelativePoseFactor> factor;
  try {
    factor.emplace(make_factor(information));
  } catch (const InvalidInputError& e) {
    // Rotation-first order: the coupling block is rows 0..2 x columns 3..5 (and its transpose).
    Matrix6 uncoupled = information;
    uncoupled.topRightCorner<3, 3>().setZero();
    uncoupled.bottomLeftCorner<3, 3>().setZero();
    if (options.drop_indefinite_coupling && uncoupled != information) {
      try {
        factor.emplace(make_factor(uncoupled));
        repaired = true;
      } catch (const InvalidInputError&) {
        // Not the coupling's fault: report the matrix as read.
      }
    }
    if (!factor) {
      std::string reason = std::string("edge ") + std::to_string(a.raw) + " " +
                           std::to_string(b.raw) + ": " + e.what();
      if (!options.drop_indefinite_coupling && uncoupled != information &&
          std::string(e.what()).find("positive definite") != std::string::npos) {
        reason +=
            " (if only the translation-rotation coupling makes it indefinite, as in "
            "cubicle.g2o, G2oReadOptions::drop_indefinite_coupling (moslam solve --drop-indefinite-coupling) reads it "
            "without the coupling)";
      }
      Fail(at, reason);
    }
  }
  out->plain_keys = out->plain_keys && (a.raw >> 56) == 0 && (b.raw >> 56) == 0;
  out->edges.push_back({a, b, numbers, at, repaired});
  out->factors.push_back(*factor);
}

// The whole stream, or Fail on a read error.
std::string ReadAll(std::istream& in, const std::string* name) {
  std::string text;
  std::array<char, 1 << 16> chunk;
  while (in) {
    in.read(chunk.data(), static_cast<std::streamsize>(chunk.size()));
    text.append(chunk.data(), static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) Fail({name, 0}, "read error");
  return text;
}

FileRecords ParseRecords(std::istream& in, const std::string* name, const G2oReadOptions& options) {
  FileRecords out;
  const std::string content = ReadAll(in, name);
  // Records are large (a factor each): reserve for every line so none is copied on growth.
  const auto lines = static_cast<std::size_t>(std::count(content.begin(), content.end(), '\n'));
  out.edges.reserve(lines + 1);
  out.factors.reserve(lines + 1);
  out.vertices.reserve(lines + 1);
  int line = 0;
  for (std::size_t begin = 0; begin < content.size();) {
    std::size_t end = content.find('\n', begin);
    if (end == std::string::npos) end = content.size();
    const std::string_view text(content.data() + begin, end - begin);
    begin = end + 1;
    if (line == std::numeric_limits<int>::max()) {
      Fail({name, line}, "file has too many lines");
    }
    ++line;
    const Location at{name, line};
    const std::vector<std::string_view> tokens = Tokenize(text);
    if (tokens.empty()) continue;
    if (tokens[0] == kVertexTag) {
      ParseVertex(tokens, 3, options, at, &out);
    } else if (tokens[0] == kEdgeTag) {
      ParseEdge(tokens, options, at, &out);
    } else if (tokens[0] == kVertex2Tag) {
      ParseVertex(tokens, 2, options, at, &out);
    } else if (tokens[0] == kEdge2Tag) {
      ParseEdge2(tokens, options, at, &out);
    } else {
      FailTag(tokens[0], at);
    }
  }
  if (out.vertices.empty() && out.edges.empty()) {
    Fail({name, 0}, "empty file: no VERTEX_SE3:QUAT, EDGE_SE3:QUAT, VERTEX_SE2 or EDGE_SE2 line");
  }
  return out;
}

std::string Describe(const DecodedId& id) {
  return "id " + std::to_string(id.raw) + " (" + ToString(id.key) + ")";
}

std::string Where(const Location& at) { return *at.file + ":" + std::to_string(at.line); }

bool IsInterRobot(const EdgeRecord& e) { return e.a.key.robot != e.b.key.robot; }

// What makes two edge lines the same edge: their keys and every number as read.
using EdgeSignature = std::tuple<Key, Key, std::array<double, kEdgeNumbers>>;

struct SignatureLess {
  bool operator()(const EdgeSignature& x, const EdgeSignature& y) const {
    if (std::get<0>(x) != std::get<0>(y)) return std::get<0>(x) < std::get<0>(y);
    if (std::get<1>(x) != std::get<1>(y)) return std::get<1>(x) < std::get<1>(y);
    return std::get<2>(x) < std::get<2>(y);
  }
};

std::string RobotFileName(std::size_t index) { return std::to_string(index) + ".g2o"; }

// Fails unless every file of the dataset has the first file's dimension (planar: 2D).
void CheckOneDimension(const std::vector<FileRecords>& files, const std::vector<std::string>& names,
                       bool planar) {
  for (std::size_t f = 1; f < files.size(); ++f) {
    if ((files[f].dimension == 2) != planar) {
      Fail({&names[f], 0}, std::string("a ") + (planar ? "3D" : "2D") +
                               " file in a dataset whose first file is " + (planar ? "2D" : "3D") +
                               ": one dataset is 2D or 3D");
    }
  }
}

// The edges a dataset keeps (with their factors): every edge, but the copy of an inter-robot
// edge that another file already holds (each copy matched once).
struct KeptEdges {
  std::vector<const EdgeRecord*> edges;
  std::vector<const RelativePoseFactor*> factors;
};

KeptEdges DropSeparatorCopies(const std::vector<FileRecords>& files) {
  // Inter-robot edges kept so far, per file, with how many copies may still be matched.
  std::map<EdgeSignature, std::map<std::size_t, int>, SignatureLess> unmatched;
  KeptEdges kept;
  for (std::size_t f = 0; f < files.size(); ++f) {
    for (std::size_t i = 0; i < files[f].edges.size(); ++i) {
      const EdgeRecord& e = files[f].edges[i];
      if (files.size() > 1 && IsInterRobot(e)) {
        auto& copies = unmatched[EdgeSignature{e.a.key, e.b.key, e.numbers}];
        const auto other = std::find_if(copies.begin(), copies.end(), [&](const auto& c) {
          return c.first != f && c.second > 0;
        });
        if (other != copies.end()) {
          --other->second;  // the other robot's copy of this edge: counted once
          continue;
        }
        ++copies[f];
      }
      kept.edges.push_back(&e);
      kept.factors.push_back(&files[f].factors[i]);
    }
  }
  return kept;
}

// Rejects an edge to a variable that no vertex line defines and no other edge connects (when the
// dataset defines vertices at all); in a folder, names the robot file that may be missing.
void RejectDangling(const std::vector<const EdgeRecord*>& kept,
                    const std::map<Key, Location>& defined, std::size_t files, bool folder,
                    bool planar) {
  if (defined.empty()) return;
  std::unordered_map<Key, int> degree;
  for (const EdgeRecord* e : kept) {
    ++degree[e->a.key];
    ++degree[e->b.key];
  }
  for (const EdgeRecord* e : kept) {
    for (const DecodedId* end : {&e->a, &e->b}) {
      if (defined.count(end->key) == 0 && degree[end->key] == 1) {
        std::string why = "dangling edge: " + Describe(*end) + " has no " +
                          std::string(planar ? kVertex2Tag : kVertexTag) +
                          " line in any file and no other edge connects it";
        const auto robot = static_cast<std::size_t>(end->key.robot);
        if (folder && robot >= files) {  // a separator to a robot without its file
          why += " (the folder holds " + RobotFileName(0) +
                 (files > 1 ? " .. " + RobotFileName(files - 1) : std::string()) + " only: is " +
                 RobotFileName(robot) + " missing?)";
        }
        Fail(e->at, why);
      }
    }
  }
}

// Merges the files of one dataset (`folder`: a distributed-mapper folder's): duplicate vertices
// are rejected, the copy of an inter-robot edge that another file already holds is dropped,
// dangling edges are rejected.
Dataset Assemble(std::vector<FileRecords>& files, const std::vector<std::string>& names,
                 bool folder) {
  Dataset data;
  data.files = names;
  data.planar = files.front().dimension == 2;
  CheckOneDimension(files, names, data.planar);
  std::map<Key, Location> defined;
  for (const FileRecords& file : files) {
    data.plain_keys = data.plain_keys && file.plain_keys;
    for (const VertexRecord& v : file.vertices) {
      const auto [it, inserted] = defined.emplace(v.id.key, v.at);
      if (!inserted) {
        Fail(v.at,
             "vertex " + Describe(v.id) + " is defined twice (first at " + Where(it->second) + ")");
      }
      data.initial.emplace(v.id.key, v.pose);
    }
  }
  const KeptEdges kept = DropSeparatorCopies(files);
  RejectDangling(kept.edges, defined, files.size(), folder, data.planar);
  for (const EdgeRecord* e : kept.edges) data.repaired_information += e->repaired ? 1 : 0;
  if (files.size() == 1) {
    // One file keeps every edge: hand its factors over without copying them.
    data.graph = PoseGraph(std::move(files.front().factors));
  } else {
    data.graph.reserve(kept.factors.size());
    for (const RelativePoseFactor* f : kept.factors) data.graph.add(*f);
  }
  return data;
}

// Full precision, locale-independent: reading the text back gives the same doubles.
void SetUpStream(std::ostream& os) {
  os.imbue(std::locale::classic());
  os << std::setprecision(std::numeric_limits<double>::max_digits10);
}

std::uint64_t FileId(const Key& key, const G2oWriteOptions& options) {
  if (options.plain_keys && key.robot == 0 && key.isPose()) {
    if (key.index > kMaxKeyIndex) {
      throw InvalidInputError("key index " + std::to_string(key.index) +
                              " does not fit in 56 bits");
    }
    return key.index;
  }
  return EncodeSymbol(key, options.scheme);
}

void WritePose(std::ostream& os, const SE3& x) {
  const Vector3& t = x.translation();
  const Eigen::Vector4d q = x.rotation().quaternionWxyz();
  os << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q[1] << ' ' << q[2] << ' ' << q[3] << ' '
     << q[0];
}

// x y theta of a planar pose; throws InvalidInputError when `x` leaves the plane by more than
// `kPlanarTolerance` (its z, or its rotation's axis off the vertical).
constexpr double kPlanarTolerance = 1e-9;
void WritePlanarPose(std::ostream& os, const SE3& x, const char* what) {
  const Matrix3& R = x.rotation().matrix();
  const Vector3& t = x.translation();
  if (!(std::abs(t.z()) <= kPlanarTolerance && std::abs(R(2, 0)) <= kPlanarTolerance &&
        std::abs(R(2, 1)) <= kPlanarTolerance && std::abs(R(0, 2)) <= kPlanarTolerance &&
        std::abs(R(1, 2)) <= kPlanarTolerance)) {
    throw InvalidInputError(std::string("G2oWriteOptions::planar: ") + what +
                            " is not planar (z = " + std::to_string(t.z()) +
                            ", or its rotation is not about the vertical): write it as SE3:QUAT");
  }
  os << t.x() << ' ' << t.y() << ' ' << std::atan2(R(1, 0), R(0, 0));
}

void WriteVertex(std::ostream& os, const Key& key, const SE3& x, const G2oWriteOptions& options) {
  if (options.planar) {
    os << kVertex2Tag << ' ' << FileId(key, options) << ' ';
    WritePlanarPose(os, x, ("the pose of " + ToString(key)).c_str());
    os << '\n';
    return;
  }
  os << kVertexTag << ' ' << FileId(key, options) << ' ';
  WritePose(os, x);
  os << '\n';
}

void WriteEdge(std::ostream& os, const RelativePoseFactor& f, const G2oWriteOptions& options) {
  const Matrix6& information = f.information();
  if (options.planar) {
    os << kEdge2Tag << ' ' << FileId(f.a(), options) << ' ' << FileId(f.b(), options) << ' ';
    WritePlanarPose(os, f.measured(), ("the measurement of " + ToString(f.a()) + " - " +
                                       ToString(f.b())).c_str());
    static constexpr int kMoslam[3] = {3, 4, 2};  // x, y, theta (ParseEdge2)
    for (int i = 0; i < 3; ++i) {
      for (int j = i; j < 3; ++j) os << ' ' << information(kMoslam[i], kMoslam[j]);
    }
    os << '\n';
    return;
  }
  os << kEdgeTag << ' ' << FileId(f.a(), options) << ' ' << FileId(f.b(), options) << ' ';
  WritePose(os, f.measured());
  for (int i = 0; i < 6; ++i) {
    for (int j = i; j < 6; ++j) os << ' ' << information(MoslamIndex(i), MoslamIndex(j));
  }
  os << '\n';
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) {
    throw Error("cannot open '" + path + "' for writing: " + std::strerror(errno));
  }
  out << text;
  out.close();
  if (!out) throw Error("failed to write '" + path + "' (disk full?)");
}

// The index of a per-robot file name "k.g2o" (no sign, no leading zero), or -1.
long long RobotFileIndex(const std::string& name) {
  constexpr std::string_view kSuffix = ".g2o";
  if (name.size() <= kSuffix.size() || name.size() > kSuffix.size() + 9) return -1;
  if (name.compare(name.size() - kSuffix.size(), kSuffix.size(), kSuffix) != 0) return -1;
  const std::string digits = name.substr(0, name.size() - kSuffix.size());
  if (digits.size() > 1 && digits[0] == '0') return -1;
  long long index = 0;
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), index);
  if (ec != std::errc() || ptr != digits.data() + digits.size() || index < 0) return -1;
  return index;
}

}  // namespace

G2oParseError::G2oParseError(std::string file, int line, std::string reason)
    : InvalidInputError(FormatError(file, line, reason)),
      file_(std::move(file)),
      line_(line),
      reason_(std::move(reason)) {}

Dataset ParseG2o(std::istream& in, const std::string& name, const G2oReadOptions& options) {
  std::vector<FileRecords> files;
  files.push_back(ParseRecords(in, &name, options));
  return Assemble(files, {name}, false);
}

Dataset ReadG2oFile(const std::string& path, const G2oReadOptions& options) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    throw G2oParseError(path, 0, "is a folder, not a g2o file (ReadG2oFolder reads folders)");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw G2oParseError(path, 0, std::string("cannot open: ") + std::strerror(errno));
  return ParseG2o(in, path, options);
}

Dataset ReadG2oFolder(const std::string& dir, const G2oReadOptions& options) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw G2oParseError(dir, 0, "is not a folder of per-robot files 0.g2o .. N-1.g2o");
  }
  std::vector<long long> indices;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const long long index = RobotFileIndex(it->path().filename().string());
    if (index >= 0) indices.push_back(index);
  }
  if (ec) throw G2oParseError(dir, 0, "cannot list the folder: " + ec.message());
  if (indices.empty()) {
    throw G2oParseError(dir, 0, "no per-robot files: expected 0.g2o .. N-1.g2o");
  }
  std::sort(indices.begin(), indices.end());
  for (std::size_t i = 0; i < indices.size(); ++i) {
    if (indices[i] != static_cast<long long>(i)) {
      throw G2oParseError(dir, 0,
                          "missing " + RobotFileName(i) +
                              ": per-robot files must be 0.g2o .. N-1.g2o without gaps (found " +
                              RobotFileName(static_cast<std::size_t>(indices[i])) + ")");
    }
  }
  std::vector<std::string> names;
  for (std::size_t i = 0; i < indices.size(); ++i) {
    names.push_back((fs::path(dir) / RobotFileName(i)).string());
  }
  std::vector<FileRecords> files;
  for (const std::string& name : names) {
    std::ifstream in(name, std::ios::binary);
    if (!in) throw G2oParseError(name, 0, std::string("cannot open: ") + std::strerror(errno));
    files.push_back(ParseRecords(in, &name, options));
  }
  return Assemble(files, names, true);
}

Dataset ReadG2o(const std::string& path, const G2oReadOptions& options) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return ReadG2oFolder(path, options);
  return ReadG2oFile(path, options);
}

void WriteG2oFile(const std::string& path, const PoseGraph& graph, const Values& values,
                  const G2oWriteOptions& options) {
  std::ostringstream os;
  SetUpStream(os);
  for (const auto& [key, pose] : values) WriteVertex(os, key, pose, options);
  for (const RelativePoseFactor& f : graph.factors()) WriteEdge(os, f, options);
  if (!options.atomic) {
    WriteText(path, os.str());
    return;
  }
  const std::string tmp = path + ".tmp";
  const auto remove_tmp = [&tmp] {
    std::error_code ignored;
    fs::remove(tmp, ignored);
  };
  try {
    WriteText(tmp, os.str());
  } catch (const Error&) {
    remove_tmp();
    throw;
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    remove_tmp();
    throw Error("cannot move '" + tmp + "' over '" + path + "': " + ec.message() + " (is '" + path +
                "' a directory?)");
  }
}

void WriteG2oFolder(const std::string& dir, const PoseGraph& graph, const Values& values,
                    const G2oWriteOptions& options) {
  int num_robots = graph.numRobots();
  for (const auto& entry : values) num_robots = std::max(num_robots, entry.first.robot + 1);
  const auto check_robot = [&](const Key& key) {
    if (key.robot < 0) {
      throw InvalidInputError("WriteG2oFolder: key " + ToString(key) + " has a negative robot");
    }
  };
  for (const auto& entry : values) check_robot(entry.first);
  for (const RelativePoseFactor& f : graph.factors()) {
    check_robot(f.a());
    check_robot(f.b());
  }
  if (num_robots <= 0) throw InvalidInputError("WriteG2oFolder: nothing to write to " + dir);

  std::vector<std::ostringstream> texts(static_cast<std::size_t>(num_robots));
  std::vector<bool> used(static_cast<std::size_t>(num_robots), false);
  for (auto& os : texts) SetUpStream(os);
  for (const auto& [key, pose] : values) {
    const auto r = static_cast<std::size_t>(key.robot);
    WriteVertex(texts[r], key, pose, options);
    used[r] = true;
  }
  for (const RelativePoseFactor& f : graph.factors()) {
    const auto ra = static_cast<std::size_t>(f.a().robot);
    const auto rb = static_cast<std::size_t>(f.b().robot);
    WriteEdge(texts[ra], f, options);
    used[ra] = true;
    if (rb != ra) {
      WriteEdge(texts[rb], f, options);
      used[rb] = true;
    }
  }
  for (std::size_t r = 0; r < used.size(); ++r) {
    if (!used[r]) {
      throw InvalidInputError("WriteG2oFolder: robot " + std::to_string(r) +
                              " has no variable and no factor, but a folder needs files for "
                              "robots 0..N-1 with no gap");
    }
  }

  CreateFolder(dir, "WriteG2oFolder");
  std::error_code ec;
  // A stale k.g2o with k >= N would be read back as part of this dataset.
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const long long index = RobotFileIndex(it->path().filename().string());
    if (index >= num_robots) {
      throw Error("cannot write a " + std::to_string(num_robots) + "-robot dataset into '" + dir +
                  "': it already holds " + it->path().filename().string() +
                  ", which would be read back as another robot; remove it or use another folder");
    }
  }
  if (ec) throw Error("cannot list folder '" + dir + "': " + ec.message());
  for (std::size_t r = 0; r < texts.size(); ++r) {
    WriteText((fs::path(dir) / RobotFileName(r)).string(), texts[r].str());
  }
}

}  // namespace moslam
