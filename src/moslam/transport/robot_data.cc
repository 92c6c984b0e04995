#include "moslam/transport/robot_data.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "moslam/common/errors.h"

namespace moslam {

Dataset ReadRobotG2o(const std::string& path, const G2oReadOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw G2oParseError(path, 0, "cannot open file");
  return ParseRobotG2o(in, path, options);
}

Dataset ParseRobotG2o(std::istream& in, const std::string& path, const G2oReadOptions& options) {
  // Two views of the file with the same line numbers: the vertex lines only, the other lines
  // only (blank lines are accepted). An edge-only view has no dangling-edge check: separators
  // to other robots' variables are expected here.
  std::string vertices, edges, line;
  bool any_vertex = false;
  while (std::getline(in, line)) {
    const auto first = line.find_first_not_of(" \t\r");
    const bool vertex = first != std::string::npos && line.compare(first, 6, "VERTEX") == 0;
    any_vertex = any_vertex || vertex;
    vertices += (vertex ? line : std::string()) + "\n";
    edges += (vertex ? std::string() : line) + "\n";
  }
  std::istringstream edge_stream(edges);
  Dataset data = ParseG2o(edge_stream, path, options);
  if (any_vertex) {
    std::istringstream vertex_stream(vertices);
    data.initial = ParseG2o(vertex_stream, path, options).initial;
  }
  return data;
}

std::string RobotFile(const std::string& folder, int robot) {
  const std::filesystem::path p = std::filesystem::path(folder) / (std::to_string(robot) + ".g2o");
  if (!std::filesystem::is_regular_file(p)) {
    throw InvalidInputError("robot " + std::to_string(robot) + ": no file " + p.string() +
                            " (a distributed-mapper folder holds 0.g2o .. N-1.g2o)");
  }
  return p.string();
}

int CountRobotFiles(const std::string& folder) {
  int n = 0;
  while (std::filesystem::is_regular_file(std::filesystem::path(folder) /
                                          (std::to_string(n) + ".g2o"))) {
    ++n;
  }
  return n;
}

}  // namespace moslam
