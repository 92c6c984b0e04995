// The k-d tree (FLANN) of a template's PFHRGB features, which the consensus and the inlier gate
// search for every segment keypoint. Built once, on first use (thread-safe: registrations of one
// class may run on several threads), and shared by every copy of the template. Before, it was
// built twice per registration (consensus and gate: 10k descriptors of 250 floats copied and
// split); k-d tree builds were 8.5 % of `moslam perceive` on house robot 1 (perf).
#pragma once

#include <pcl/kdtree/kdtree_flann.h>

#include <mutex>

#include "moslam/pose_estimation/features.h"

namespace moslam {

class TemplateFeatureIndex {
 public:
  using Tree = pcl::KdTreeFLANN<pcl::PFHRGBSignature250>;

  explicit TemplateFeatureIndex(PfhrgbCloud::ConstPtr features);
  TemplateFeatureIndex(const TemplateFeatureIndex&) = delete;
  TemplateFeatureIndex& operator=(const TemplateFeatureIndex&) = delete;

  // The descriptors indexed (a registration checks it is its template's).
  const PfhrgbCloud* features() const { return features_.get(); }

  // A search handle on the shared index with its own approximation factor (0 = exact search);
  // builds the index on the first call.
  Tree::Ptr tree(float epsilon) const;

 private:
  PfhrgbCloud::ConstPtr features_;
  mutable std::once_flag built_;
  mutable Tree tree_;
};

}  // namespace moslam
