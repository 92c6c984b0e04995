// Symmetric objects and the agreement score: when two poses of a template look alike to the
// score (registration.h, AGREEMENT RULE), the feature evidence of the inlier gate decides between
// them (registration.h, SYMMETRIC TIE-BREAK).
//
// A fridge is a box: turned by a quarter or a half turn about its vertical axis, its points land
// on its own surface with its own colour (self-agreement 0.97 for each turn, measured on the
// house scenario's model), so the coarse score ranks the right pose and its turns within noise of
// one another, and the wrong one often wins. A chair is not (0.48-0.49): for it the score is the
// evidence, and no tie-break applies.
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "moslam/geometry/se3.h"
#include "moslam/pose_estimation/object_template.h"
#include "moslam/pose_estimation/registration.h"

namespace moslam {

// The fraction of the template's points q (at most 2000 of them, evenly strided) for which some
// template point lies within config.score_distance of motion * q (object frame) with a
// chromaticity within config.colour_tolerance of q's (the AGREEMENT RULE without depth noise).
// 1: a pose and that pose moved by `motion` look the same to the score; 0 for an empty template.
double TemplateSelfAgreement(const ObjectTemplate& tmpl, const SE3& motion,
                             const RegistrationConfig& config);

// A hypothesis after its coarse GICP (registration.h): its index, object_T_camera (segment into
// the object frame) and coarse score.
struct CoarsePose {
  int hypothesis = -1;
  Eigen::Matrix4f object_T_camera = Eigen::Matrix4f::Identity();
  double score = 0.0;
};

// The SYMMETRIC TIE-BREAK of registration.h. `ranked` holds the coarse poses best first;
// ranked[0] won, and its refined pose failed the inlier gate. Returns the indices of the others
// to refine instead, best first: those
// - whose coarse score is within config.tie_break_score_margin of the winner's;
// - whose motion from the winner (ranked[i] * ranked[0]^-1) is nearest a turn of the object by
//   360 j / symmetry_turns degrees about its vertical axis with j != 0 (another side of the
//   object, not the winner's pose found twice);
// - under which turn, and under that motion itself, the template's self-agreement is at least
//   config.min_symmetry_self_agreement (the turn: the object has that symmetry; the motion: the
//   two poses are related by it);
// - whose coarse pose holds the gate on its own (gate_count(object_T_camera) >= min_inliers).
// Empty when config.symmetric_tie_break is off.
std::vector<std::size_t> SymmetricTieBreakOrder(
    const std::vector<CoarsePose>& ranked, const ObjectTemplate& tmpl,
    const std::function<int(const Eigen::Matrix4f&)>& gate_count,
    const RegistrationConfig& config);

}  // namespace moslam
