// v4r - robust model-based object tracking. MIT licence.
// Template building and the cache: round trip, keys, and stale or corrupt files rebuilt, never
// trusted (truncated, bit-flipped, other key).
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "v4r/detection/template_cache.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;
using namespace v4r::detection;
namespace fs = std::filesystem;

namespace {

/// A small view range so that the tests build quickly.
DetectorParams small_params() {
  DetectorParams p;
  p.views.elevation_min_deg = 30;
  p.views.elevation_max_deg = 50;
  p.views.azimuth_min_deg = 0;
  p.views.azimuth_max_deg = 60;
  p.views.inplane_min_deg = -10;
  p.views.inplane_max_deg = 10;
  p.views.distance_min_m = 0.5;
  p.views.distance_max_m = 0.7;
  return p;
}

model::Model box_model() { return std::move(*model::parse_cao(synth::box_cao(), "box")); }

fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("v4r_detection_" + name + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string read_all(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}
void write_all(const fs::path& p, const std::string& s) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(s.data(), static_cast<std::streamsize>(s.size()));
}

}  // namespace

TEST(Templates, GridCoarseLevelAndChildrenCoverEveryView) {
  const auto m = box_model();
  auto ts = build_templates(m, synth::default_camera(), small_params());
  ASSERT_TRUE(ts) << ts.error().to_string();
  EXPECT_EQ(ts->views.size(), static_cast<std::size_t>(ts->n_elevation * ts->n_azimuth * ts->n_inplane * ts->n_distance));
  EXPECT_EQ(ts->fine.templates.size(), ts->views.size());
  EXPECT_LT(ts->coarse.templates.size() * 8, ts->views.size());  // the coarse level is small
  std::vector<int> covered(ts->views.size(), 0);
  for (const auto v : ts->children) covered[v] = 1;
  for (std::size_t v = 0; v < covered.size(); ++v) EXPECT_TRUE(covered[v]) << "view " << v << " is nobody's child";
  for (const Template& t : ts->fine.templates) {
    EXPECT_GE(t.count, 8u);
    EXPECT_LE(t.count, 63u);
  }
}

TEST(Templates, BadInputIsAnErrorNamingTheField) {
  const auto m = box_model();
  DetectorParams p = small_params();
  p.views.inplane_min_deg = 20;
  auto ts = build_templates(m, synth::default_camera(), p);
  ASSERT_FALSE(ts);
  EXPECT_EQ(ts.error().field, "detect.views.inplane_min");
  geometry::PinholeCamera cam;  // no focal length
  EXPECT_FALSE(build_templates(m, cam, small_params()));
}

TEST(TemplateCache, KeyFollowsModelCameraAndViewRange) {
  const auto m = box_model();
  const auto cam = synth::default_camera();
  const DetectorParams p = small_params();
  const std::uint64_t k = template_key(m, cam, p);
  EXPECT_EQ(k, template_key(m, cam, p));
  DetectorParams q = p;
  q.views.elevation_max_deg = 55;
  EXPECT_NE(k, template_key(m, cam, q));
  q = p;
  q.search.coarse_candidates = 7;  // search parameters do not change the templates
  EXPECT_EQ(k, template_key(m, cam, q));
  auto cam2 = cam;
  cam2.fx += 1;
  EXPECT_NE(k, template_key(m, cam2, p));
  const auto flange = std::move(*model::parse_cao(synth::flange_cao(), "f"));
  EXPECT_NE(k, template_key(flange, cam, p));
}

TEST(TemplateCache, RoundTripAndRebuildOfStaleOrCorruptFiles) {
  const auto m = box_model();
  const auto cam = synth::default_camera();
  const DetectorParams p = small_params();
  const fs::path dir = temp_dir("cache");
  CacheReport rep;
  auto first = load_or_build(m, cam, p, dir.string(), &rep);
  ASSERT_TRUE(first) << first.error().to_string();
  EXPECT_TRUE(rep.built);
  EXPECT_TRUE(rep.written) << rep.write_error;
  EXPECT_EQ(rep.reason, "no cache file");
  ASSERT_TRUE(fs::exists(rep.path));
  const std::string path = rep.path;

  auto second = load_or_build(m, cam, p, dir.string(), &rep);
  ASSERT_TRUE(second);
  EXPECT_FALSE(rep.built);  // read from the cache
  const TemplateSet& a = **first;
  const TemplateSet& b = **second;
  ASSERT_EQ(a.views.size(), b.views.size());
  EXPECT_EQ(a.fine.features.size(), b.fine.features.size());
  EXPECT_EQ(a.children, b.children);
  for (std::size_t i = 0; i < a.fine.features.size(); ++i) {
    EXPECT_EQ(a.fine.features[i].x, b.fine.features[i].x);
    EXPECT_EQ(a.fine.features[i].orientation, b.fine.features[i].orientation);
  }
  EXPECT_TRUE(a.views[5].T_cam_obj.translation().isApprox(b.views[5].T_cam_obj.translation()));

  const std::string good = read_all(path);
  // Truncated: rebuilt, and the file is whole again.
  write_all(path, good.substr(0, good.size() / 2));
  auto r = read_templates(path, template_key(m, cam, p));
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("corrupt"), std::string::npos) << r.error().message;
  ASSERT_TRUE(load_or_build(m, cam, p, dir.string(), &rep));
  EXPECT_TRUE(rep.built);
  EXPECT_NE(rep.reason.find("corrupt"), std::string::npos);
  EXPECT_EQ(read_all(path), good);

  // One bit flipped in the payload: the checksum catches it.
  std::string flipped = good;
  flipped[flipped.size() - 100] = static_cast<char>(flipped[flipped.size() - 100] ^ 0x10);
  write_all(path, flipped);
  r = read_templates(path, template_key(m, cam, p));
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("checksum"), std::string::npos) << r.error().message;
  EXPECT_EQ(r.error().file, path);
  ASSERT_TRUE(load_or_build(m, cam, p, dir.string(), &rep));
  EXPECT_TRUE(rep.built);
  EXPECT_EQ(read_all(path), good);

  // A file of another key under this name (e.g. copied by hand): stale.
  r = read_templates(path, template_key(m, cam, p) + 1);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("stale"), std::string::npos);

  // Garbage of the right length with a valid-looking header but no magic.
  write_all(path, std::string(good.size(), 'x'));
  EXPECT_FALSE(read_templates(path, template_key(m, cam, p)));
  fs::remove_all(dir);
}

TEST(TemplateCache, UnwritableFolderStillGivesTemplates) {
  const auto m = box_model();
  const fs::path dir = temp_dir("ro");
  const fs::path file = dir / "not_a_folder";
  write_all(file, "x");
  CacheReport rep;
  auto ts = load_or_build(m, synth::default_camera(), small_params(), file.string(), &rep);
  ASSERT_TRUE(ts);
  EXPECT_FALSE(rep.written);
  EXPECT_FALSE(rep.write_error.empty());
  fs::remove_all(dir);
}
