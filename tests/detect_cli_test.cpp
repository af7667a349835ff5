// v4r - robust model-based object tracking. MIT licence.
// `v4r prepare` and `v4r detect` end to end: templates built once and then read from the cache,
// a corrupt cache rebuilt, the rendered box found at its true pose, clear errors on bad input.
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "cli_harness.hpp"

namespace fs = std::filesystem;

namespace {

using v4r_test::CliRun;

class DetectCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("v4r_detect_cli_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const CliRun r = run("render --model box --frames 1 --out " + (dir_ / "seq").string());
    ASSERT_EQ(r.code, 0) << r.err;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static CliRun run(const std::string& args) { return v4r_test::run_cli(V4R_CLI, args, dir_); }
  static std::string seq(const std::string& f) { return (dir_ / "seq" / f).string(); }
  /// A narrow view range around the rendered start pose (azimuth -34 deg, elevation 43 deg), so that
  /// the test builds quickly.
  static std::string common() {
    return "--model " + seq("model.cao") + " --camera " + seq("camera.yaml") +
           " --views elevation=30:55,azimuth=-60:-10,inplane=-10:10,distance=0.5:0.7 --cache-dir " + (dir_ / "cache").string();
  }
  static inline fs::path dir_;
};

TEST_F(DetectCli, PrepareCachesAndDetectFindsTheTruePose) {
  CliRun r = run("prepare " + common());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("built"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("templates of"), std::string::npos) << r.out;
  r = run("detect " + common() + " --input " + seq("frames/000000.png"));
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_NE(r.err.find("from the cache"), std::string::npos) << r.err;
  // First line after the comment: pose tx ty tz rx ry rz score=... verified; the truth is
  // init_pose.txt (the box's symmetries give other rotation vectors of the same appearance, so
  // only the translation of the box's centre, its origin, is compared).
  std::istringstream out(r.out);
  std::string line;
  double tx = 0, ty = 0, tz = 0;
  bool found = false;
  while (std::getline(out, line))
    if (line.rfind("pose ", 0) == 0 && line.find("verified") != std::string::npos) {
      std::istringstream ls(line.substr(5));
      ls >> tx >> ty >> tz;
      found = true;
      break;
    }
  ASSERT_TRUE(found) << r.out;
  std::ifstream f(seq("init_pose.txt"));
  std::string l;
  double t[3] = {0, 0, 0};
  while (std::getline(f, l))
    if (!l.empty() && l[0] != '#') {
      std::istringstream ls(l);
      ls >> t[0] >> t[1] >> t[2];
    }
  EXPECT_LT(std::hypot(tx - t[0], ty - t[1], tz - t[2]), 0.01) << r.out;
}

TEST_F(DetectCli, CorruptCacheIsRebuilt) {
  ASSERT_EQ(run("prepare " + common()).code, 0);
  fs::path file;
  for (const auto& e : fs::directory_iterator(dir_ / "cache"))
    if (e.path().extension() == ".v4rt") file = e.path();
  ASSERT_FALSE(file.empty());
  fs::resize_file(file, fs::file_size(file) / 3);
  const CliRun r = run("prepare " + common());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("corrupt"), std::string::npos) << r.err;
}

TEST_F(DetectCli, BadInputIsNamed) {
  CliRun r = run("detect " + common() + " --input " + (dir_ / "missing.png").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("missing.png"), std::string::npos) << r.err;
  r = run("prepare --model " + seq("model.cao") + " --views elevation=50:20");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("detect.views.elevation_min"), std::string::npos) << r.err;
  r = run("prepare --model " + seq("model.cao") + " --views height=1:2");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--views"), std::string::npos) << r.err;
  r = run("prepare --model " + seq("model.cao") + " --set detect.verify.accept_score=2");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("detect.verify.accept_score"), std::string::npos) << r.err;
}

TEST_F(DetectCli, TheGreenSpongeIsFoundThroughItsColourRegion) {
  // data/sponge.cao (built in as "sponge"): every face colour=0.2,0.6,0.1.
  CliRun r = run("render --model sponge --frames 1 --distance 0.35 --out " + (dir_ / "sponge").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string cam = (dir_ / "sponge" / "camera.yaml").string(), img = (dir_ / "sponge" / "frames" / "000000.png").string();
  const std::string views = " --views elevation=30:55,azimuth=-60:-10,inplane=-10:10,distance=0.3:0.4 --cache-dir " +
                            (dir_ / "cache").string();
  r = run("detect --model sponge --camera " + cam + " --input " + img + views);
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_NE(r.out.find("# colour stage: 1 region(s)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(" verified\n"), std::string::npos) << r.out;
  // The same with the colour stage off: the whole image is searched.
  r = run("detect --model sponge --camera " + cam + " --input " + img + views + " --set detect.colour.enabled=false");
  EXPECT_EQ(r.out.find("# colour stage"), std::string::npos) << r.out;
  // The steel box has no green: with --colour, nothing of that colour, no hypothesis.
  r = run("detect " + common() + " --colour 0.2,0.6,0.1 --input " + seq("frames/000000.png"));
  EXPECT_EQ(r.code, 3) << r.err << r.out;
  EXPECT_NE(r.out.find("# colour stage: 0 region(s)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("# 0 verified of 0 hypotheses"), std::string::npos) << r.out;
}

TEST_F(DetectCli, BadColourIsNamed) {
  CliRun r = run("detect " + common() + " --colour 0.2,1.5,0.1 --input " + seq("frames/000000.png"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--colour"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("component G must be a number in 0..1, found '1.5'"), std::string::npos) << r.err;
  r = run("track --model " + seq("model.cao") + " --camera " + seq("camera.yaml") + " --input " + seq("frames") +
          " --output " + (dir_ / "c.csv").string() + " --colour green");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--colour"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("expected R,G,B"), std::string::npos) << r.err;
}

TEST_F(DetectCli, ConfigListsTheDetectorParametersAndTrackAcceptsThem) {
  const CliRun r = run("config");
  ASSERT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("accept_score"), std::string::npos);
  EXPECT_NE(r.out.find("elevation_min"), std::string::npos);
  EXPECT_NE(r.out.find("max_distance"), std::string::npos);  // detect.colour.*
  std::ofstream(dir_ / "my.yaml") << r.out;
  const CliRun t = run("track --model " + seq("model.cao") + " --camera " + seq("camera.yaml") + " --input " + seq("frames") +
                       " --init-pose-file " + seq("init_pose.txt") + " --output " + (dir_ / "p.csv").string() +
                       " --config " + (dir_ / "my.yaml").string());
  EXPECT_EQ(t.code, 0) << t.err;
}

}  // namespace
