#include "moslam/pose_estimation/feature_index.h"

#include <memory>
#include <utility>

#include "moslam/common/errors.h"

namespace moslam {

TemplateFeatureIndex::TemplateFeatureIndex(PfhrgbCloud::ConstPtr features)
    : features_(std::move(features)) {
  if (!features_ || features_->empty()) {
    throw InvalidInputError("TemplateFeatureIndex: the template has no features");
  }
}

TemplateFeatureIndex::Tree::Ptr TemplateFeatureIndex::tree(float epsilon) const {
  std::call_once(built_, [this] { tree_.setInputCloud(features_); });
  // A copy shares the FLANN index and the descriptors (shared pointers); searches are const.
  auto handle = std::make_shared<Tree>(tree_);
  handle->setEpsilon(epsilon);
  return handle;
}

}  // namespace moslam
