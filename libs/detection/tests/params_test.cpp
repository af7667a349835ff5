// v4r - robust model-based object tracking. MIT licence.
// Detector parameters: every one registered with a unit or range, and cross-field checks that
// name the field.
#include <gtest/gtest.h>

#include "v4r/detection/detector_params.hpp"
#include "v4r/detection/gradient_pyramid.hpp"

using namespace v4r;
using namespace v4r::detection;

TEST(DetectorParams, EveryParameterIsRegisteredUnderDetectWithADoc) {
  DetectorParams p;
  ParamRegistry r;
  add_params(r, p);
  ASSERT_GE(r.entries().size(), 30u);
  for (const auto& e : r.entries()) {
    EXPECT_EQ(e.name.rfind("detect.", 0), 0u) << e.name;
    EXPECT_FALSE(e.doc.empty()) << e.name;
    EXPECT_LT(e.lo, e.hi) << e.name;
  }
  ASSERT_TRUE(r.set("detect.views.elevation_max", "60"));
  EXPECT_EQ(p.views.elevation_max_deg, 60.0);
  EXPECT_EQ(r.find("detect.views.distance_min")->unit, "m");
  EXPECT_EQ(r.find("detect.views.azimuth_max")->unit, "deg");
  EXPECT_FALSE(r.set("detect.search.coarse_spread", "99"));  // out of range
}

TEST(DetectorParams, DefaultsAreValid) { EXPECT_TRUE(validate(DetectorParams{})); }

TEST(DetectorParams, CrossFieldErrorsNameTheField) {
  DetectorParams p;
  p.views.elevation_min_deg = 50;
  p.views.elevation_max_deg = 20;
  auto r = validate(p);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().field, "detect.views.elevation_min");
  p = DetectorParams{};
  p.views.distance_min_m = 2.0;
  p.views.distance_max_m = 1.0;
  r = validate(p);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().field, "detect.views.distance_min");
}

TEST(Orientation, QuantisesModulo180DegreesIntoEightBins) {
  EXPECT_EQ(quantise_orientation(1, 0), 0);
  EXPECT_EQ(quantise_orientation(-1, 0), 0);  // polarity ignored (atan2 = 180 deg wraps to bin 0)
  EXPECT_EQ(quantise_orientation(0, 1), 4);
  EXPECT_EQ(quantise_orientation(0, -1), 4);
  EXPECT_EQ(quantise_orientation(1, 1), 2);
  EXPECT_EQ(quantise_orientation(-1, 1), 6);
  EXPECT_EQ(quantise_gradient_orientation(-1, 1), 6);
  EXPECT_EQ(quantise_gradient_orientation(3, -1), 7);
  EXPECT_EQ(orientation_similarity(0, 0), 4);
  EXPECT_EQ(orientation_similarity(0, 7), 1);  // neighbours across the wrap
  EXPECT_EQ(orientation_similarity(0, 2), 0);
}

TEST(Orientation, IntegerGradientsQuantiseAsAtan2Does) {
  // Every Sobel response of an 8-bit image (|g| <= 4 x 255), boundary ties included.
  int differ = 0;
  for (int gx = -1020; gx <= 1020; ++gx)
    for (int gy = -1020; gy <= 1020; ++gy)
      if ((gx != 0 || gy != 0) && quantise_gradient_orientation(gx, gy) != quantise_orientation(gx, gy)) ++differ;
  EXPECT_EQ(differ, 0);
}
