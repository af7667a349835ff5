// v4r - robust model-based object tracking. MIT licence.

#include "v4r/io/scene_file.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "v4r/io/camera_io.hpp"

namespace v4r::io {
namespace {

namespace fs = std::filesystem;

/// \brief A temporary folder with what a scene file points at: two calibrations, a model and two
/// frame folders; removed at scope exit.
class SceneDir {
 public:
  SceneDir() {
    std::string tmpl = (fs::temp_directory_path() / "v4r_io_scene_XXXXXX").string();
    path_ = ::mkdtemp(tmpl.data()) != nullptr ? fs::path(tmpl) : fs::path();
    if (path_.empty()) return;
    geometry::PinholeCamera cam;
    cam.fx = cam.fy = 600.0;
    cam.cx = 320.0;
    cam.cy = 240.0;
    cam.width = 640;
    cam.height = 480;
    (void)save_camera_opencv(file("left.yaml"), cam);
    (void)save_camera_opencv(file("right.yaml"), cam);
    write("part.cao", "V1\n0\n0\n0\n0\n0\n0\n");
    fs::create_directories(path_ / "frames_left");
    fs::create_directories(path_ / "frames_right");
  }
  ~SceneDir() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  SceneDir(const SceneDir&) = delete;
  SceneDir& operator=(const SceneDir&) = delete;
  [[nodiscard]] std::string file(const std::string& name) const { return (path_ / name).string(); }
  [[nodiscard]] bool ok() const { return !path_.empty(); }
  void write(const std::string& name, const std::string& text) const { std::ofstream(file(name)) << text; }
  /// Writes `text` as scene.yaml and loads it.
  [[nodiscard]] Expected<SceneFile> load(const std::string& text) const {
    write("scene.yaml", text);
    return load_scene_file(file("scene.yaml"));
  }

 private:
  fs::path path_;
};

constexpr const char* kGood = R"(reference_frame: rig
cameras:
  - name: left
    calibration: left.yaml
    input: frames_left
  - name: right
    calibration: right.yaml
    input: frames_right
    T_ref_cam: [0.12, 0, 0, 0, -0.087, 0]
objects:
  - name: part
    model: part.cao
    model_units: mm
    init_pose: [0.05, 0.1, 0.6, 2.0, 0.1, -0.5]
  - name: fixture
    model: part.cao
)";

TEST(SceneFile, ReadsCamerasAndObjectsWithPathsRelativeToTheFile) {
  SceneDir d;
  ASSERT_TRUE(d.ok());
  auto s = d.load(kGood);
  ASSERT_TRUE(s) << s.error().to_string();
  EXPECT_EQ(s->reference_frame, "rig");
  ASSERT_EQ(s->cameras.size(), 2u);
  EXPECT_EQ(s->cameras[0].name, "left");
  EXPECT_EQ(fs::path(s->cameras[0].calibration_path), fs::path(d.file("left.yaml")));
  EXPECT_EQ(fs::path(s->cameras[1].input), fs::path(d.file("frames_right")));
  EXPECT_DOUBLE_EQ(s->cameras[0].calibration.fx, 600.0);
  EXPECT_EQ(s->cameras[0].calibration.width, 640);
  EXPECT_TRUE(s->cameras[0].T_ref_cam.translation().isZero());
  EXPECT_NEAR(s->cameras[1].T_ref_cam.translation().x(), 0.12, 1e-12);
  EXPECT_NEAR(s->cameras[1].T_ref_cam.log()[4], -0.087, 1e-9);
  EXPECT_EQ(s->cameras[1].input_at.line, 8);
  ASSERT_EQ(s->objects.size(), 2u);
  EXPECT_EQ(s->objects[0].name, "part");
  EXPECT_DOUBLE_EQ(s->objects[0].scale, 1e-3);
  ASSERT_TRUE(s->objects[0].init_pose.has_value());
  EXPECT_NEAR(s->objects[0].init_pose->translation().z(), 0.6, 1e-12);
  EXPECT_FALSE(s->objects[1].init_pose.has_value());
  EXPECT_DOUBLE_EQ(s->objects[1].scale, 1.0);
  EXPECT_EQ(s->objects[1].at.line, 15);
}

TEST(SceneFile, ObjectsAndInputsAreOptional) {
  SceneDir d;
  ASSERT_TRUE(d.ok());
  auto s = d.load("cameras:\n  - name: c\n    calibration: left.yaml\n");
  ASSERT_TRUE(s) << s.error().to_string();
  EXPECT_TRUE(s->objects.empty());
  EXPECT_TRUE(s->cameras[0].input.empty());
  EXPECT_EQ(s->reference_frame, "ref");
}

TEST(SceneFile, LiveAndSchemeInputsAreNotPaths) {
  SceneDir d;
  ASSERT_TRUE(d.ok());
  auto s = d.load("cameras:\n  - name: a\n    calibration: left.yaml\n    input: ros2:/camera/image\n"
                  "  - name: b\n    calibration: left.yaml\n    input: frames_left/%06d.png\n");
  ASSERT_TRUE(s) << s.error().to_string();
  EXPECT_EQ(s->cameras[0].input, "ros2:/camera/image");
  EXPECT_EQ(fs::path(s->cameras[1].input), fs::path(d.file("frames_left/%06d.png")));
}

TEST(SceneFile, ReadsAnObjectsTagAndColourAsTheCommandLineTakesThem) {
  SceneDir d;
  ASSERT_TRUE(d.ok());
  auto s = d.load("cameras:\n  - name: c\n    calibration: left.yaml\nobjects:\n"
                  "  - name: sponge\n    model: part.cao\n"
                  "    tag: \"tag36h11:7:0.08:0.01 -0.02 0.05 3.14159265 0 0\"\n"
                  "    colour: [0.2, 0.6, 0.1]\n"
                  "  - name: plain\n    model: part.cao\n"
                  "  - name: quoted\n    model: part.cao\n    tag: 'tag25h9:3:0.1:\"0, 0, 0.02, 0, 0.5, 0\"'\n"
                  "    colour: \"1,0,0.5\"\n");
  ASSERT_TRUE(s) << s.error().to_string();
  ASSERT_EQ(s->objects.size(), 3u);
  const SceneObjectSpec& a = s->objects[0];
  ASSERT_TRUE(a.tag.has_value());
  EXPECT_EQ(a.tag->family, "tag36h11");
  EXPECT_EQ(a.tag->id, 7);
  EXPECT_DOUBLE_EQ(a.tag->size_m, 0.08);
  EXPECT_TRUE(a.tag->T_obj_tag.translation().isApprox(Eigen::Vector3d(0.01, -0.02, 0.05), 1e-12));
  EXPECT_NEAR(a.tag->T_obj_tag.rvec().norm(), 3.14159265, 1e-6);
  EXPECT_EQ(a.tag_at.line, 7);
  EXPECT_EQ(a.tag_at.field, "objects[0].tag");
  // The same text as --tag gives the same tag.
  auto cli = detection::parse_tag_spec("tag36h11:7:0.08:\"0.01 -0.02 0.05 3.14159265 0 0\"", "--tag");
  ASSERT_TRUE(cli);
  EXPECT_TRUE(cli->T_obj_tag.matrix().isApprox(a.tag->T_obj_tag.matrix(), 1e-12));
  ASSERT_TRUE(a.colour.has_value());
  EXPECT_TRUE(a.colour->isApprox(Eigen::Vector3f(0.2f, 0.6f, 0.1f)));
  EXPECT_FALSE(s->objects[1].tag.has_value());
  EXPECT_FALSE(s->objects[1].colour.has_value());
  ASSERT_TRUE(s->objects[2].tag.has_value());
  EXPECT_EQ(s->objects[2].tag->family, "tag25h9");
  EXPECT_EQ(s->objects[2].tag->id, 3);
  EXPECT_TRUE(s->objects[2].tag->T_obj_tag.translation().isApprox(Eigen::Vector3d(0, 0, 0.02), 1e-12));
  ASSERT_TRUE(s->objects[2].colour.has_value());
  EXPECT_TRUE(s->objects[2].colour->isApprox(Eigen::Vector3f(1.0f, 0.0f, 0.5f)));
}

/// One broken scene file: what the error must name.
struct BadCase {
  const char* what;
  std::string text;
  int line;
  const char* field;
  const char* message_part;
};

TEST(SceneFile, EveryErrorNamesFileLineAndField) {
  SceneDir d;
  ASSERT_TRUE(d.ok());
  const std::string cam = "cameras:\n  - name: left\n    calibration: left.yaml\n";
  const std::string obj = cam + "objects:\n  - name: p\n    model: part.cao\n";
  const BadCase cases[] = {
      {"unknown top-level key", "camras:\n  - name: x\n", 1, "camras", "unknown key"},
      {"unknown camera key", cam + "    focal: 3\n", 4, "cameras[0].focal", "unknown key"},
      {"unknown object key", cam + "objects:\n  - name: p\n    model: part.cao\n    pose: [0,0,1,0,0,0]\n", 7,
       "objects[0].pose", "unknown key"},
      {"missing calibration file", "cameras:\n  - name: left\n    calibration: nope.yaml\n", 3, "cameras[0].calibration",
       "no such file"},
      {"missing input", cam + "    input: no_frames\n", 4, "cameras[0].input", "no such file"},
      {"missing model file", cam + "objects:\n  - name: p\n    model: nope.cao\n", 6, "objects[0].model", "no such file"},
      {"pose of five numbers", cam + "    T_ref_cam: [0, 0, 0, 0, 0]\n", 4, "cameras[0].T_ref_cam", "six numbers"},
      {"pose not a number", cam + "objects:\n  - name: p\n    model: part.cao\n    init_pose: [0, 0, x, 0, 0, 0]\n", 7,
       "objects[0].init_pose", "not a number"},
      {"pose in degrees", cam + "    T_ref_cam: [0, 0, 0, 0, 90, 0]\n", 4, "cameras[0].T_ref_cam", "2 pi"},
      {"duplicate camera", cam + "  - name: left\n    calibration: right.yaml\n", 4, "cameras[1].name", "duplicate"},
      {"duplicate object", cam + "objects:\n  - name: p\n    model: part.cao\n  - name: p\n    model: part.cao\n", 7,
       "objects[1].name", "duplicate"},
      {"no cameras", "objects:\n  - name: p\n    model: part.cao\n", 1, "cameras", "no cameras"},
      {"empty camera list", "cameras: []\n", 1, "cameras", "no cameras"},
      {"camera without name", "cameras:\n  - calibration: left.yaml\n", 2, "cameras[0].name", "missing"},
      {"bad units", cam + "objects:\n  - name: p\n    model: part.cao\n    model_units: inch\n", 7,
       "objects[0].model_units", "mm, cm or m"},
      {"object name that leaves the output folder", cam + "objects:\n  - name: ../p\n    model: part.cao\n", 5,
       "objects[0].name", "names files"},
      {"camera name with a slash", "cameras:\n  - name: a/b\n    calibration: left.yaml\n", 2, "cameras[0].name",
       "names files"},
      {"calibration that does not load", "cameras:\n  - name: left\n    calibration: part.cao\n", 3,
       "cameras[0].calibration", "does not load"},
      {"unknown tag family", obj + "    tag: \"tag99h1:0:0.08:0 0 0 0 0 0\"\n", 7, "objects[0].tag",
       "unknown tag family 'tag99h1'"},
      {"tag id not a number", obj + "    tag: \"tag36h11:x:0.08:0 0 0 0 0 0\"\n", 7, "objects[0].tag",
       "field 'id'"},
      {"tag size not a number", obj + "    init_pose: [0, 0, 1, 0, 0, 0]\n    tag: \"tag36h11:0:big:0 0 0 0 0 0\"\n", 8,
       "objects[0].tag", "field 'size_m'"},
      {"tag pose number", obj + "    tag: \"tag36h11:0:0.08:0 0 zero 0 0 0\"\n", 7, "objects[0].tag",
       "field 'tz'"},
      {"tag pose of five numbers", obj + "    tag: \"tag36h11:0:0.08:0 0 0 0 0\"\n", 7, "objects[0].tag",
       "field 'rz': missing"},
      {"tag pose of seven numbers", obj + "    tag: \"tag36h11:0:0.08:0 0 0 0 0 0 1\"\n", 7, "objects[0].tag",
       "seventh number"},
      {"tag without size", obj + "    tag: \"tag36h11:0\"\n", 7, "objects[0].tag", "field 'size_m': missing"},
      {"tag as a list", obj + "    tag: [tag36h11, 0]\n", 7, "objects[0].tag", "one string"},
      {"colour of two numbers", obj + "    colour: [0.2, 0.6]\n", 7, "objects[0].colour", "expected R,G,B"},
      {"colour of four numbers", obj + "    colour: [0.2, 0.6, 0.1, 1]\n", 7, "objects[0].colour", "found more"},
      {"colour out of range", obj + "    colour: [0.2, 255, 0.1]\n", 7, "objects[0].colour",
       "component G must be a number in 0..1"},
      {"colour not a number", obj + "    colour: [red, 0, 0]\n", 7, "objects[0].colour", "component R"},
      {"colour as a mapping", obj + "    colour: {r: 1}\n", 7, "objects[0].colour", "three numbers"},
  };
  for (const BadCase& c : cases) {
    SCOPED_TRACE(c.what);
    auto s = d.load(c.text);
    ASSERT_FALSE(s);
    const Error& e = s.error();
    EXPECT_EQ(e.file, d.file("scene.yaml"));
    EXPECT_EQ(e.line, c.line) << e.to_string();
    EXPECT_EQ(e.field, c.field) << e.to_string();
    EXPECT_NE(e.message.find(c.message_part), std::string::npos) << e.to_string();
    EXPECT_NE(e.to_string().find(d.file("scene.yaml") + ":" + std::to_string(c.line)), std::string::npos);
  }
}

TEST(SceneFile, GarbageNeverCrashes) {
  SceneDir d;
  ASSERT_TRUE(d.ok());
  const char* garbage[] = {"",           "[1, 2",       "cameras: {a: 1}", "cameras:\n  - 3\n", ":\n:\n- -",
                           "\t\x01\xff", "cameras: 7",  "- a\n- b\n",      "cameras:\n  - name: [1]\n",
                           "cameras:\n  - name: c\n    calibration: left.yaml\n    T_ref_cam: {a: 1}\n",
                           "cameras:\n  - name: c\n    calibration: left.yaml\nobjects: 5\n"};
  for (const char* g : garbage) {
    SCOPED_TRACE(g);
    auto s = d.load(g);
    ASSERT_FALSE(s);
    EXPECT_FALSE(s.error().message.empty());
    EXPECT_EQ(s.error().file, d.file("scene.yaml"));
  }
}

TEST(SceneFile, MutatedFilesNeverCrashAndErrorsNameTheFile) {
  SceneDir d;
  ASSERT_TRUE(d.ok());
  const std::string good = kGood;
  const char kAlphabet[] = "-:[],{}#&*!|>'\"%@` \n\t0123456789.eEabcxyz";
  std::mt19937 rng(11);
  for (int trial = 0; trial < 400; ++trial) {
    std::string text = good;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      const std::size_t at = rng() % text.size();
      const char c = kAlphabet[rng() % (sizeof(kAlphabet) - 1)];
      switch (rng() % 3) {
        case 0: text[at] = c; break;
        case 1: text.insert(text.begin() + static_cast<long>(at), c); break;
        default: text.erase(at, 1 + rng() % 8); break;
      }
    }
    SCOPED_TRACE(text);
    auto s = d.load(text);
    if (!s) {
      EXPECT_FALSE(s.error().message.empty());
      EXPECT_EQ(s.error().file, d.file("scene.yaml"));
    }
  }
}

TEST(SceneFile, MissingSceneFileIsAnError) {
  auto s = load_scene_file("/nonexistent/scene.yaml");
  ASSERT_FALSE(s);
  EXPECT_EQ(s.error().file, "/nonexistent/scene.yaml");
}

}  // namespace
}  // namespace v4r::io
