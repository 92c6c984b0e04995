#include "moslam/io/tum.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <locale>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <system_error>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/common/number_text.h"
#include "moslam/common/whole_file.h"

namespace moslam {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void Fail(const std::string& path, int line, const std::string& reason) {
  throw InvalidInputError(path + ":" + std::to_string(line) + ": " + reason);
}

std::vector<std::string_view> Tokenize(std::string_view line) {
  const auto hash = line.find('#');
  if (hash != std::string_view::npos) line = line.substr(0, hash);
  static constexpr std::string_view kBlanks = " \t\r\v\f";
  std::vector<std::string_view> tokens;
  std::size_t pos = 0;
  while ((pos = line.find_first_not_of(kBlanks, pos)) != std::string_view::npos) {
    std::size_t end = line.find_first_of(kBlanks, pos);
    if (end == std::string_view::npos) end = line.size();
    tokens.push_back(line.substr(pos, end - pos));
    pos = end;
  }
  return tokens;
}

// A whole token as a finite double, locale-independent (common/number_text.h).
double ParseNumber(std::string_view token, const std::string& path, int line) {
  double value = 0.0;
  const NumberStatus status = ParseNumberToken(token, value);
  if (status != NumberStatus::kOk) {
    Fail(path, line, "'" + std::string(token.substr(0, 40)) + "' " + NumberStatusReason(status, "a double"));
  }
  return value;
}

void WriteTrajectory(const std::string& path,
                     const std::vector<std::pair<std::uint64_t, SE3>>& poses) {
  std::ostringstream os;
  os.imbue(std::locale::classic());
  os << std::setprecision(std::numeric_limits<double>::max_digits10);
  for (const auto& [index, x] : poses) {
    const Vector3& t = x.translation();
    const Eigen::Vector4d q = x.rotation().quaternionWxyz();  // w x y z
    os << index << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q[1] << ' ' << q[2] << ' '
       << q[3] << ' ' << q[0] << '\n';
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error("cannot open '" + path + "' for writing: " + std::strerror(errno));
  out << os.str();
  out.close();
  if (!out) throw Error("failed to write '" + path + "' (disk full?)");
}

}  // namespace

std::vector<std::string> WriteTumTrajectories(const std::string& dir, const Values& values) {
  CreateFolder(dir, "WriteTumTrajectories");
  // Values is ordered by robot, then poses before objects, then index.
  std::vector<std::string> written;
  auto it = values.begin();
  while (it != values.end()) {
    const int robot = it->first.robot;
    const VariableKind kind = it->first.kind;
    std::vector<std::pair<std::uint64_t, SE3>> poses;
    for (; it != values.end() && it->first.robot == robot && it->first.kind == kind; ++it) {
      poses.emplace_back(it->first.index, it->second);
    }
    const std::string name = "robot_" + std::to_string(robot) +
                             (kind == VariableKind::kObject ? "_objects" : "") + ".tum";
    const std::string path = (fs::path(dir) / name).string();
    WriteTrajectory(path, poses);
    written.push_back(path);
  }
  return written;
}

Values ParseTumTrajectory(std::istream& in, const std::string& name, int robot) {
  if (robot < 0 || robot >= kMaxRobots) {
    throw InvalidInputError("ReadTumTrajectory: robot " + std::to_string(robot) +
                            " is out of range [0, " + std::to_string(kMaxRobots) + ")");
  }
  Values values;
  std::string text;
  int line = 0;
  std::uint64_t index = 0;
  while (std::getline(in, text)) {
    ++line;
    const std::vector<std::string_view> tokens = Tokenize(text);
    if (tokens.empty()) continue;
    if (tokens.size() != 8) {
      Fail(name, line,
           "expected 8 fields (timestamp tx ty tz qx qy qz qw), found " +
               std::to_string(tokens.size()));
    }
    double v[8];
    for (std::size_t i = 0; i < 8; ++i) v[i] = ParseNumber(tokens[i], name, line);
    if (v[4] == 0.0 && v[5] == 0.0 && v[6] == 0.0 && v[7] == 0.0) {
      Fail(name, line, "quaternion (qx qy qz qw) is zero");
    }
    SO3 rotation;
    try {  // any finite non-zero norm is normalised, without overflow or underflow
      rotation = SO3::FromQuaternion(v[7], v[4], v[5], v[6]);
    } catch (const std::invalid_argument& e) {
      Fail(name, line, std::string("quaternion cannot be normalised: ") + e.what());
    }
    values.emplace(Key::Pose(robot, index++), SE3(rotation, Vector3(v[1], v[2], v[3])));
  }
  if (in.bad()) Fail(name, line, "read error after this line");
  return values;
}

Values ReadTumTrajectory(const std::string& path, int robot) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InvalidInputError("cannot open '" + path + "': " + std::strerror(errno));
  return ParseTumTrajectory(in, path, robot);
}

}  // namespace moslam
