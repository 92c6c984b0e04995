// Variable keys: every variable belongs to one robot and is a pose or an object landmark.
//
// On file a key is a 64-bit GTSAM Symbol, (uint64(c) << 56) | index (shared/CONVENTIONS.md):
// robot r writes its poses with the r-th character of kRobotChars and, where a file holds objects
// (KeyScheme::kWithObjects), its objects with the upper-case form of its character. Upper-case
// characters are therefore poses of robots 26..51 in kPosesOnly files and objects of robots 0..25
// in kWithObjects files; the two cannot be mixed (the trap the reference implementation fell in).
// A raw id below 2^56 (character byte 0) is a plain integer key: pose `id` of robot 0.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

namespace moslam {

enum class VariableKind : std::uint8_t { kPose = 0, kObject = 1 };

enum class KeyScheme { kPosesOnly, kWithObjects };

inline constexpr char kRobotChars[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ";
inline constexpr int kMaxRobots = 52;
inline constexpr int kMaxRobotsWithObjects = 26;
inline constexpr std::uint64_t kMaxKeyIndex = (std::uint64_t{1} << 56) - 1;

struct Key {
  int robot = 0;
  VariableKind kind = VariableKind::kPose;
  std::uint64_t index = 0;

  static Key Pose(int robot, std::uint64_t index) { return {robot, VariableKind::kPose, index}; }
  static Key Object(int robot, std::uint64_t index) {
    return {robot, VariableKind::kObject, index};
  }
  bool isPose() const { return kind == VariableKind::kPose; }
  bool isObject() const { return kind == VariableKind::kObject; }

  // Ordered by robot, then poses before objects, then index.
  friend bool operator<(const Key& a, const Key& b) {
    if (a.robot != b.robot) return a.robot < b.robot;
    if (a.kind != b.kind) return a.kind < b.kind;
    return a.index < b.index;
  }
  friend bool operator==(const Key& a, const Key& b) {
    return a.robot == b.robot && a.kind == b.kind && a.index == b.index;
  }
  friend bool operator!=(const Key& a, const Key& b) { return !(a == b); }
};

// "a12" style: the Symbol character and index ("x12" for plain keys would be ambiguous, so plain
// keys print as robot 0's). Objects print with their upper-case character.
std::string ToString(const Key& key);

// Throws InvalidInputError when the key has no encoding under `scheme` (robot out of range,
// index >= 2^56, objects of robot >= 26).
std::uint64_t EncodeSymbol(const Key& key, KeyScheme scheme);
// Throws InvalidInputError when the character byte is neither 0 nor a robot character.
Key DecodeSymbol(std::uint64_t raw, KeyScheme scheme);

}  // namespace moslam

template <>
struct std::hash<moslam::Key> {
  std::size_t operator()(const moslam::Key& k) const noexcept {
    return std::hash<std::uint64_t>()((std::uint64_t(k.robot) << 57) ^
                                      (std::uint64_t(k.kind) << 56) ^ k.index);
  }
};
