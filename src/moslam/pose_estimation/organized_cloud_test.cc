#include "moslam/pose_estimation/organized_cloud.h"

#include <gtest/gtest.h>

#include <cmath>

#include "moslam/common/errors.h"

namespace moslam {
namespace {

RgbdFrame SmallFrame() {
  RgbdFrame f;
  f.intrinsics = PinholeIntrinsics{};
  f.rgb = cv::Mat(240, 320, CV_8UC3, cv::Scalar(10, 20, 30));
  f.depth = cv::Mat(240, 320, CV_32FC1, cv::Scalar(2.0f));
  return f;
}

TEST(OrganizedCloud, BackProjectsPixelsAndMarksMissingDepthNaN) {
  RgbdFrame f = SmallFrame();
  f.depth.at<float>(5, 7) = 0.0f;
  f.depth.at<float>(6, 7) = -1.0f;
  f.depth.at<float>(100, 40) = 3.0f;
  f.rgb.at<cv::Vec3b>(100, 40) = cv::Vec3b(1, 2, 3);  // B G R
  const auto cloud = MakeOrganizedCloud(f);
  ASSERT_EQ(cloud->width, 320u);
  ASSERT_EQ(cloud->height, 240u);
  EXPECT_FALSE(cloud->is_dense);
  EXPECT_TRUE(std::isnan(cloud->at(7, 5).z));
  EXPECT_TRUE(std::isnan(cloud->at(7, 6).x));
  const auto& p = cloud->at(40, 100);
  const PinholeIntrinsics& K = f.intrinsics;
  EXPECT_NEAR(p.x, (40 - K.cx) * 3.0 / K.fx, 1e-6);
  EXPECT_NEAR(p.y, (100 - K.cy) * 3.0 / K.fy, 1e-6);
  EXPECT_FLOAT_EQ(p.z, 3.0f);
  EXPECT_EQ(p.b, 1);
  EXPECT_EQ(p.g, 2);
  EXPECT_EQ(p.r, 3);
}

TEST(OrganizedCloud, ProjectInvertsBackProject) {
  const PinholeIntrinsics K;
  const Vector3 p = BackProject(K, 12.25, 200.5, 1.7);
  const auto uv = Project(K, p);
  ASSERT_TRUE(uv.has_value());
  EXPECT_NEAR(uv->x(), 12.25, 1e-9);
  EXPECT_NEAR(uv->y(), 200.5, 1e-9);
  EXPECT_FALSE(Project(K, Vector3(0.0, 0.0, -1.0)).has_value());
  const Eigen::Vector2i pix = PixelOfIndex(3 * 320 + 17, 320);
  EXPECT_EQ(pix.x(), 17);
  EXPECT_EQ(pix.y(), 3);
}

TEST(OrganizedCloud, RejectsMismatchedImages) {
  RgbdFrame f = SmallFrame();
  f.depth = cv::Mat(240, 320, CV_16UC1, cv::Scalar(0));
  EXPECT_THROW(MakeOrganizedCloud(f), InvalidInputError);
  f = SmallFrame();
  f.rgb = cv::Mat(200, 320, CV_8UC3);
  EXPECT_THROW(MakeOrganizedCloud(f), InvalidInputError);
}

}  // namespace
}  // namespace moslam
