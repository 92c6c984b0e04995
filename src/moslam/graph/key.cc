#include "moslam/graph/key.h"

#include <cstring>
#include <string>

#include "moslam/common/errors.h"

namespace moslam {

std::string ToString(const Key& key) {
  if (key.robot < 0 || key.robot >= kMaxRobots) {
    return "robot" + std::to_string(key.robot) + (key.isPose() ? ".x" : ".o") +
           std::to_string(key.index);
  }
  char c = kRobotChars[key.robot];
  if (key.isObject()) c = static_cast<char>(c - 'a' + 'A');
  return std::string(1, c) + std::to_string(key.index);
}

std::uint64_t EncodeSymbol(const Key& key, KeyScheme scheme) {
  if (key.index > kMaxKeyIndex) {
    throw InvalidInputError("key index " + std::to_string(key.index) + " does not fit in 56 bits");
  }
  const int limit = (scheme == KeyScheme::kWithObjects) ? kMaxRobotsWithObjects : kMaxRobots;
  if (key.robot < 0 || key.robot >= limit) {
    throw InvalidInputError("robot " + std::to_string(key.robot) + " has no key character (at most " +
                            std::to_string(limit) + " robots" +
                            (scheme == KeyScheme::kWithObjects ? " in files with objects)" : ")"));
  }
  if (key.isObject() && scheme != KeyScheme::kWithObjects) {
    throw InvalidInputError("object key " + ToString(key) + " needs KeyScheme::kWithObjects");
  }
  char c = kRobotChars[key.robot];
  if (key.isObject()) c = static_cast<char>(c - 'a' + 'A');
  return (std::uint64_t(static_cast<unsigned char>(c)) << 56) | key.index;
}

Key DecodeSymbol(std::uint64_t raw, KeyScheme scheme) {
  const auto c = static_cast<char>(raw >> 56);
  const std::uint64_t index = raw & kMaxKeyIndex;
  if (c == 0) return Key::Pose(0, index);
  const char* pos = std::strchr(kRobotChars, c);
  if (pos == nullptr) {
    throw InvalidInputError("id " + std::to_string(raw) + " is out of range: its top byte " +
                            std::to_string(static_cast<unsigned char>(c)) +
                            " is not a robot character (a-z, A-Z)");
  }
  const int r = static_cast<int>(pos - kRobotChars);
  if (r >= 26 && scheme == KeyScheme::kWithObjects) return Key::Object(r - 26, index);
  return Key::Pose(r, index);
}

}  // namespace moslam
