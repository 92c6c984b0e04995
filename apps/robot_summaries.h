// The robots' summary.json files (`moslam robot --out DIR`, robot_command.cc) as `moslam team`
// reads them back: each robot's exit code, and the summary of every robot that finished, with
// every field it reads checked.
//
// `moslam robot` writes its summary whole (a temporary file renamed), but a summary is still a
// file: another version's, edited, or damaged in a copy. Every read names the file, the field (and
// the array element) it wanted and the likely cause:
//   robot1/summary.json: field "pose_rounds" is missing (written by another version of `moslam
//   robot`, or edited?)
// as an InvalidInputError; nothing else escapes (no nlohmann exception).
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <type_traits>
#include <vector>

namespace moslam::cli {

// A JSON value with the place it came from ("<file>" or "<file>: solves[2]"): its fields read
// with their types checked.
class JsonFields {
 public:
  JsonFields(nlohmann::json value, std::string where);

  // Parses `text` (the contents of `where`). Throws InvalidInputError when it is not JSON.
  static JsonFields Parse(const std::string& text, const std::string& where);

  // Field `key` of an object as T: an integer type (a JSON integer within T's range), a floating
  // type (any JSON number), bool, std::string, or a std::vector of those (a JSON array). Throws
  // InvalidInputError when this is not an object, the field is missing, or it is not a T.
  template <class T>
  T get(const std::string& key) const {
    return convert<T>(field(key), "field \"" + key + "\"");
  }
  // The elements of the array field `key`, each named "<where>: key[i]"; an absent field is an
  // error unless `optional` (then no elements).
  std::vector<JsonFields> items(const std::string& key, bool optional = false) const;
  // This value as T (an element of an array); the same types and errors.
  template <class T>
  T as() const {
    return convert<T>(value_, "the value");
  }

  const nlohmann::json& json() const { return value_; }
  const std::string& where() const { return where_; }

 private:
  template <class T>
  struct IsVector : std::false_type {};
  template <class E>
  struct IsVector<std::vector<E>> : std::true_type {};

  const nlohmann::json& field(const std::string& key) const;
  [[noreturn]] void throwWrongType(const std::string& what, const char* expected) const;

  template <class T>
  T convert(const nlohmann::json& v, const std::string& what) const {
    if constexpr (IsVector<T>::value) {
      if (!v.is_array()) throwWrongType(what, "an array");
      T out;
      out.reserve(v.size());
      for (std::size_t i = 0; i < v.size(); ++i) {
        out.push_back(convert<typename T::value_type>(v[i], what + "[" + std::to_string(i) + "]"));
      }
      return out;
    } else if constexpr (std::is_same_v<T, bool>) {
      if (!v.is_boolean()) throwWrongType(what, "a boolean");
      return v.get<bool>();
    } else if constexpr (std::is_integral_v<T>) {
      using Limits = std::numeric_limits<T>;
      const auto max = static_cast<std::uint64_t>(Limits::max());
      if (v.is_number_unsigned()) {
        const auto u = v.get<std::uint64_t>();
        if (u <= max) return static_cast<T>(u);
      } else if (v.is_number_integer()) {
        const auto i = v.get<std::int64_t>();
        if (i >= 0 ? static_cast<std::uint64_t>(i) <= max
                   : i >= static_cast<std::int64_t>(Limits::min())) {
          return static_cast<T>(i);
        }
      }
      throwWrongType(what, "an integer within range");
    } else if constexpr (std::is_floating_point_v<T>) {
      if (!v.is_number()) throwWrongType(what, "a number");
      return v.get<T>();
    } else {
      static_assert(std::is_same_v<T, std::string>, "JsonFields: an unsupported type");
      if (!v.is_string()) throwWrongType(what, "a string");
      return v.get<std::string>();
    }
  }

  nlohmann::json value_;
  std::string where_;
};

// The team's summaries: ok when every robot exited 0 and left a summary.json; `failed` holds the
// robots that did not.
struct TeamSummaries {
  bool ok = true;
  // robot -> {robot, reason; exit_code when known, log when it exists}
  std::map<int, nlohmann::json> failed;
  std::map<int, JsonFields> summaries;   // robot -> its summary, those that finished
};

// Reads <out>/robot<R>/summary.json for R = 0 .. n-1; `exit_codes` holds the exit codes of the
// robots this process ran (-1: killed at the timeout; a robot absent from it was started
// elsewhere, `team --collect`: it finished when its summary is there). Throws InvalidInputError
// when a summary cannot be read or is not JSON.
TeamSummaries ReadTeamSummaries(const std::filesystem::path& out, int n,
                                const std::map<int, int>& exit_codes);

}  // namespace moslam::cli
