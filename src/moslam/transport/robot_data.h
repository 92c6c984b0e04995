// The data one robot process owns: its own file R.g2o of a distributed-mapper folder (its
// vertices, its inner edges and its separators, whose other end is another robot's variable
// defined only in that robot's file).
#pragma once

#include <istream>
#include <string>

#include "moslam/io/g2o.h"

namespace moslam {

// Reads one robot's file: the vertices as the initial values, every edge as a factor. Unlike
// ReadG2oFile, an edge to a variable no vertex of this file defines is accepted (a separator);
// every other rule of io/g2o.h applies, errors name the file and line. Throws G2oParseError.
Dataset ReadRobotG2o(const std::string& path, const G2oReadOptions& options = {});
// The same from a stream; `path` names the file in the messages.
Dataset ParseRobotG2o(std::istream& in, const std::string& path,
                      const G2oReadOptions& options = {});

// "<folder>/<robot>.g2o". Throws InvalidInputError when the file does not exist.
std::string RobotFile(const std::string& folder, int robot);

// Number of robot files 0.g2o, 1.g2o, ... present in `folder` (consecutive from 0).
int CountRobotFiles(const std::string& folder);

}  // namespace moslam
