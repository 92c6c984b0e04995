#include "robot_summaries.h"

#include <fmt/core.h>

#include <utility>

#include "moslam/common/errors.h"
#include "moslam/common/whole_file.h"

namespace moslam::cli {

namespace fs = std::filesystem;

namespace {
constexpr const char* kLikelyCause = " (written by another version of `moslam robot`, or edited?)";
}  // namespace

JsonFields::JsonFields(nlohmann::json value, std::string where)
    : value_(std::move(value)), where_(std::move(where)) {}

JsonFields JsonFields::Parse(const std::string& text, const std::string& where) {
  nlohmann::json value = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded()) {
    throw InvalidInputError(fmt::format(
        "{}: not JSON (damaged or cut short, or not a robot's summary?)", where));
  }
  return JsonFields(std::move(value), where);
}

const nlohmann::json& JsonFields::field(const std::string& key) const {
  if (!value_.is_object()) {
    throw InvalidInputError(fmt::format("{}: a JSON object expected, found {}{}", where_,
                                        value_.type_name(), kLikelyCause));
  }
  const auto it = value_.find(key);
  if (it == value_.end()) {
    throw InvalidInputError(
        fmt::format("{}: field \"{}\" is missing{}", where_, key, kLikelyCause));
  }
  return *it;
}

void JsonFields::throwWrongType(const std::string& what, const char* expected) const {
  throw InvalidInputError(fmt::format("{}: {} is not {}{}", where_, what, expected, kLikelyCause));
}

std::vector<JsonFields> JsonFields::items(const std::string& key, bool optional) const {
  std::vector<JsonFields> out;
  if (optional && value_.is_object() && !value_.contains(key)) return out;
  const nlohmann::json& array = field(key);
  if (!array.is_array()) throwWrongType("field \"" + key + "\"", "an array");
  out.reserve(array.size());
  for (std::size_t i = 0; i < array.size(); ++i) {
    out.emplace_back(array[i], fmt::format("{}: {}[{}]", where_, key, i));
  }
  return out;
}

TeamSummaries ReadTeamSummaries(const fs::path& out, int n, const std::map<int, int>& exit_codes) {
  TeamSummaries t;
  for (int r = 0; r < n; ++r) {
    const fs::path dir = out / fmt::format("robot{}", r);
    const auto code = exit_codes.find(r);
    const bool ran = code != exit_codes.end();  // by this process: its exit code is known
    const int exit_code = ran ? code->second : 0;
    const fs::path file = dir / "summary.json";
    if (exit_code != 0 || !fs::exists(file)) {
      t.ok = false;
      nlohmann::json& f = t.failed[r];
      f = {{"robot", r}};
      if (ran) f["exit_code"] = exit_code;
      f["reason"] = exit_code == -1  ? std::string("killed at the timeout")
                    : exit_code != 0 ? fmt::format("exit {}", exit_code)
                                     : fmt::format("no {} ({})", file.string(),
                                                   ran ? "it exited 0" : "it has not finished");
      const fs::path log = dir / "log.txt";
      if (fs::exists(log)) f["log"] = log.string();
      continue;
    }
    t.summaries.emplace(r, JsonFields::Parse(ReadWholeFileOrThrow(file.string()), file.string()));
  }
  return t;
}

}  // namespace moslam::cli
