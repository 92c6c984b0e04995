// g2o pose-graph files (shared/CONVENTIONS.md, "g2o files"):
//   VERTEX_SE3:QUAT id x y z qx qy qz qw
//   EDGE_SE3:QUAT i j x y z qx qy qz qw  I11 I12 .. I16 I22 .. I66   (upper triangle, row by row,
//                                        g2o order x y z rx ry rz; permuted to (rotation,
//                                        translation) on read and back on write, never rescaled)
// Ids are GTSAM Symbol keys (graph/key.h). Quaternions are normalised on read.
//
// 2D files read as planar SE(3) graphs (Dataset::planar), the 3D code unchanged:
//   VERTEX_SE2 id x y theta                -> (Rz(theta), (x, y, 0))
//   EDGE_SE2 i j x y theta  I11 I12 I13 I22 I23 I33   (information on x, y, theta) -> the same
//   measurement, that information on (tx, ty, rz), and the out-of-plane directions the information
//   of their in-plane counterparts (rx, ry: theta's; tz: the mean of x's and y's). A planar graph
//   started in the plane stays there (the problem is symmetric under z -> -z), so those entries
//   only condition the system. The cost is moslam's, 1/2 r^T Omega r with the exact SE(3) Log
//   (shared/CONVENTIONS.md), not g2o's SE2 error, whose translation part is not the Log's: the
//   two agree to second order in the residuals. A file holds 2D or 3D lines, not both.
//
// Accepted: edges without vertices (initialise with the chordal relaxation), i > j, parallel
// edges, blank lines and '#' comments. Rejected with G2oParseError (file, line, reason): unknown
// tags, wrong field counts, non-numbers, NaN/Inf, information
// that is not symmetric positive definite, an id whose Symbol character is not a robot letter, a
// vertex defined twice, an empty file, and in a file that has vertices an edge to a vertex that
// no file defines and no other edge connects (a dangling edge).
//
// A multi-robot dataset is a folder of 0.g2o .. N-1.g2o (distributed-mapper layout): each file
// holds its robot's vertices and edges; an inter-robot edge appears in both robots' files and is
// counted once. Other files in the folder (fullGraph.g2o) are ignored.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "moslam/common/errors.h"
#include "moslam/graph/pose_graph.h"

namespace moslam {

class G2oParseError : public InvalidInputError {
 public:
  G2oParseError(std::string file, int line, std::string reason);
  const std::string& file() const { return file_; }
  int line() const { return line_; }  // 1-based; 0 when the error concerns the whole file
  const std::string& reason() const { return reason_; }

 private:
  std::string file_;
  int line_;
  std::string reason_;
};

struct G2oReadOptions {
  // How upper-case Symbol characters read: poses of robots 26..51, or objects of robots 0..25.
  KeyScheme scheme = KeyScheme::kPosesOnly;
  // Some published files hold information matrices that are indefinite only because of their
  // translation-rotation coupling block: datasets/pgo/cubicle.g2o, 5021 of 16869 edges (x-y, z-rx
  // and z-ry entries set, both 3x3 diagonal blocks positive definite). By default such an edge is
  // rejected like any matrix that is not SPD. With this set, the coupling block of exactly those
  // edges is zeroed (the diagonal blocks are kept as read and must be SPD) and the edges so changed
  // are counted in Dataset::repaired_information.
  bool drop_indefinite_coupling = false;
};

struct Dataset {
  PoseGraph graph;
  Values initial;                   // from VERTEX lines: may be empty (edge-only files) or partial
  bool plain_keys = true;           // every id read was a plain integer (character byte 0)
  bool planar = false;              // read from VERTEX_SE2 / EDGE_SE2 lines
  std::vector<std::string> files;   // the files read, in order
  int repaired_information = 0;     // edges read with G2oReadOptions::drop_indefinite_coupling
};

// Parses g2o text; `name` is used in error messages.
Dataset ParseG2o(std::istream& in, const std::string& name, const G2oReadOptions& options = {});
Dataset ReadG2oFile(const std::string& path, const G2oReadOptions& options = {});
Dataset ReadG2oFolder(const std::string& dir, const G2oReadOptions& options = {});
// A file or a distributed-mapper folder, by what `path` is.
Dataset ReadG2o(const std::string& path, const G2oReadOptions& options = {});

struct G2oWriteOptions {
  KeyScheme scheme = KeyScheme::kPosesOnly;
  bool plain_keys = false;  // write robot 0's poses as plain integers (single-robot files)
  // Write VERTEX_SE2 / EDGE_SE2 lines (a Dataset read with `planar`): every pose and measurement
  // must lie in the plane (z and the rotation's tilt within 1e-9), else InvalidInputError.
  bool planar = false;
  // Write `path` whole or not at all: the text goes to `path` + ".tmp", which is then renamed over
  // `path`, so a reader (or a process restarted after a crash) sees the old file or the new one,
  // never half of one. On failure the temporary file is removed and `path` is left as it was.
  bool atomic = false;
};

// Writes vertices for every variable in `values` and one edge per factor (priors are not
// written: g2o has no standard prior tag). Full double precision, so a round trip is exact.
// Throws moslam::Error when the file cannot be written (or, with `atomic`, renamed into place).
void WriteG2oFile(const std::string& path, const PoseGraph& graph, const Values& values,
                  const G2oWriteOptions& options = {});
// Writes 0.g2o .. N-1.g2o into `dir` (created if missing): each robot's vertices and its
// edges, inter-robot edges into both robots' files.
void WriteG2oFolder(const std::string& dir, const PoseGraph& graph, const Values& values,
                    const G2oWriteOptions& options = {});

}  // namespace moslam
