// v4r - robust model-based object tracking. MIT licence.
#include <gtest/gtest.h>

#include "v4r/core/params.hpp"

namespace {
struct Params {
  int rows = 24;
  double sigma = 0.5;
  float grad = 8.0f;
  bool cues = true;
};
v4r::ParamRegistry registry(Params& p) {
  v4r::ParamRegistry r;
  r.add("track.rows", &p.rows, 3, 256, "", "samples along the edge");
  r.add("solver.sigma", &p.sigma, 0.01, 10.0, "px", "line noise");
  r.add("track.min_gradient", &p.grad, 0.0, 255.0, "grey/px", "edge threshold");
  r.add("track.use_cues", &p.cues, "cue integration");
  return r;
}
}  // namespace

TEST(ParamRegistry, SetGetAndRanges) {
  Params p;
  auto r = registry(p);
  ASSERT_TRUE(r.set("track.rows", "32"));
  EXPECT_EQ(p.rows, 32);
  ASSERT_TRUE(r.set("solver.sigma", " 0.75 "));
  EXPECT_DOUBLE_EQ(p.sigma, 0.75);
  ASSERT_TRUE(r.set("track.use_cues", "off"));
  EXPECT_FALSE(p.cues);
  EXPECT_EQ(*r.get("track.rows"), "32");
  EXPECT_EQ(r.find("track.rows")->default_value, "24");

  struct Bad {
    const char* name;
    const char* value;
    const char* fragment;
  };
  for (const Bad& b : {Bad{"track.rows", "2", "out of range"}, Bad{"track.rows", "3.5", "whole number"},
                       Bad{"track.rows", "abc", "expected a number"}, Bad{"solver.sigma", "nan", "finite"},
                       Bad{"solver.sigma", "1e400", "expected a number"}, Bad{"track.use_cues", "maybe", "true or false"},
                       Bad{"track.rowz", "3", "did you mean 'track.rows'"}, Bad{"nothing.like.it", "1", "unknown parameter"},
                       Bad{"track.rows", "", "expected a number"}}) {
    auto res = r.set(b.name, b.value);
    ASSERT_FALSE(res) << b.name << "=" << b.value;
    EXPECT_EQ(res.error().field, b.name);
    EXPECT_NE(res.error().message.find(b.fragment), std::string::npos) << res.error().message;
  }
  EXPECT_EQ(p.rows, 32) << "a rejected value leaves the parameter untouched";
}

TEST(ParamRegistry, YamlIsNestedAndCommented) {
  Params p;
  auto r = registry(p);
  const std::string y = r.to_yaml();
  EXPECT_NE(y.find("track:\n  rows: 24"), std::string::npos) << y;
  EXPECT_NE(y.find("solver:\n  sigma: 0.5"), std::string::npos) << y;
  EXPECT_NE(y.find("[px]"), std::string::npos) << y;
}
