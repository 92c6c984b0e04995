// TUM RGB-D trajectory files: one line per pose, "timestamp tx ty tz qx qy qz qw".
#pragma once

#include <istream>
#include <string>

#include "moslam/graph/pose_graph.h"

namespace moslam {

// Writes one file per robot into `dir` (created if missing): robot_<r>.tum with that robot's
// poses in index order, the pose index as timestamp (g2o files carry no time), and, when the
// robot has object landmarks, robot_<r>_objects.tum the same way. Returns the paths written.
// Throws moslam::Error when a file cannot be written.
std::vector<std::string> WriteTumTrajectories(const std::string& dir, const Values& values);

// Reads a TUM file (comments '#' allowed) into poses of `robot` indexed 0..n-1 in file order.
// Throws InvalidInputError naming the line on malformed input.
Values ReadTumTrajectory(const std::string& path, int robot = 0);
// The same from a stream; `name` stands for the file in the messages.
Values ParseTumTrajectory(std::istream& in, const std::string& name, int robot = 0);

}  // namespace moslam
