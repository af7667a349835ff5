// v4r - robust model-based object tracking. MIT licence.
#include <set>

#include <gtest/gtest.h>

#include "v4r/pipeline/params.hpp"

TEST(CycleParams, EveryDefaultIsInsideItsRangeAndNamesAreUnique) {
  v4r::pipeline::CycleParams p;
  const v4r::ParamRegistry r = v4r::pipeline::make_registry(p);
  std::set<std::string> names;
  for (const auto& e : r.entries()) {
    EXPECT_TRUE(names.insert(e.name).second) << e.name;
    EXPECT_FALSE(e.doc.empty()) << e.name;
    // Setting each parameter to its own default must be accepted (default within range).
    v4r::ParamRegistry copy = r;
    EXPECT_TRUE(copy.set(e.name, e.default_value)) << e.name << " = " << e.default_value;
  }
  EXPECT_GE(names.size(), 25u);
}

TEST(CycleParams, RegistryWritesThroughToTheStruct) {
  v4r::pipeline::CycleParams p;
  v4r::ParamRegistry r = v4r::pipeline::make_registry(p);
  ASSERT_TRUE(r.set("track.rows", "16"));
  ASSERT_TRUE(r.set("solver.line_sigma", "0.7"));
  EXPECT_EQ(p.track.rows, 16);
  EXPECT_DOUBLE_EQ(p.line_sigma_px, 0.7);
}
