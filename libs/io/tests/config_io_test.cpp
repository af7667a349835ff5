// v4r - robust model-based object tracking. MIT licence.
#include <gtest/gtest.h>

#include "v4r/io/config_io.hpp"

namespace {
struct P {
  int rows = 24;
  double sigma = 0.5;
  bool cues = true;
};
v4r::ParamRegistry reg(P& p) {
  v4r::ParamRegistry r;
  r.add("track.rows", &p.rows, 3, 256, "", "rows");
  r.add("solver.line_sigma", &p.sigma, 0.01, 10, "px", "sigma");
  r.add("track.use_cues", &p.cues, "cues");
  return r;
}
}  // namespace

TEST(ConfigIo, NestedKeysSetParameters) {
  P p;
  auto r = reg(p);
  ASSERT_TRUE(v4r::io::apply_config_text("track:\n  rows: 32\n  use_cues: false\nsolver: {line_sigma: 0.8}\n", "c.yaml", r));
  EXPECT_EQ(p.rows, 32);
  EXPECT_FALSE(p.cues);
  EXPECT_DOUBLE_EQ(p.sigma, 0.8);
  ASSERT_TRUE(v4r::io::apply_config_text("", "empty.yaml", r));
}

TEST(ConfigIo, RoundTripOfTheEffectiveConfiguration) {
  P p;
  auto r = reg(p);
  p.rows = 40;
  p.sigma = 1.25;
  const std::string y = r.to_yaml();
  P q;
  auto r2 = reg(q);
  ASSERT_TRUE(v4r::io::apply_config_text(y, "effective.yaml", r2)) << y;
  EXPECT_EQ(q.rows, 40);
  EXPECT_DOUBLE_EQ(q.sigma, 1.25);
}

TEST(ConfigIo, ErrorsNameFileLineAndKeyAndChangeNothing) {
  struct Case {
    const char* text;
    int line, column;
    const char* field;
    const char* fragment;
  };
  for (const Case& c : {Case{"track:\n  rows: 32\n  rowz: 3\n", 3, 9, "track.rowz", "did you mean"},
                        Case{"track:\n  rows: 1000\n", 2, 9, "track.rows", "out of range"},
                        Case{"solver:\n  line_sigma: fast\n", 2, 15, "solver.line_sigma", "expected a number"},
                        Case{"track:\n  rows: [1, 2]\n", 2, 3, "track.rows", "expected a value"},
                        Case{"track:\n  rows: 32\n bad indent: 1\n", 3, 0, "", ""},
                        Case{"- 1\n- 2\n", 1, 1, "", "mapping"}}) {
    P p;
    auto r = reg(p);
    auto res = v4r::io::apply_config_text(c.text, "cfg.yaml", r);
    ASSERT_FALSE(res) << c.text;
    EXPECT_EQ(res.error().file, "cfg.yaml");
    EXPECT_EQ(res.error().line, c.line) << c.text << " -> " << res.error().to_string();
    if (c.column) {
      EXPECT_EQ(res.error().column, c.column) << res.error().to_string();
    }
    EXPECT_EQ(res.error().field, c.field);
    EXPECT_NE(res.error().message.find(c.fragment), std::string::npos) << res.error().to_string();
    EXPECT_EQ(p.rows, 24) << "nothing changes when the file has an error: " << c.text;
  }
  P p;
  auto r = reg(p);
  EXPECT_FALSE(v4r::io::apply_config_file("/nonexistent/cfg.yaml", r));
}
