// v4r - robust model-based object tracking. MIT licence.
// Face colours: the colour covering most area, and a colour given for a whole model.
#include <gtest/gtest.h>

#include "v4r/model/cao_reader.hpp"
#include "v4r/model/model_colour.hpp"

using namespace v4r::model;

namespace {
// A 2 x 1 rectangle (area 2, green) and a unit triangle (area 0.5, red) twice: red sums to 1.
const char* kText =
    "6\n0 0 0\n2 0 0\n2 1 0\n0 1 0\n0 0 1\n1 0 1\n0\n0\n3\n"
    "4 0 1 2 3 colour=0.2,0.6,0.1\n"
    "3 0 1 4 colour=0.9,0.1,0.1\n"
    "3 0 5 4 colour=0.9,0.1,0.1\n";
}  // namespace

TEST(ModelColour, DominantColourIsTheOneCoveringMostArea) {
  auto m = parse_cao(kText, "c.cao");
  ASSERT_TRUE(m) << m.error().to_string();
  EXPECT_NEAR(face_area(*m, m->faces()[0]), 2.0, 1e-12);
  EXPECT_NEAR(face_area(*m, m->faces()[1]), 1.0, 1e-12);
  const auto c = dominant_face_colour(*m);
  ASSERT_TRUE(c.has_value());
  EXPECT_TRUE(c->isApprox(Eigen::Vector3f(0.2f, 0.6f, 0.1f)));
}

TEST(ModelColour, NoColouredFaceGivesNoColourAndAGivenColourCoversEveryFace) {
  auto m = parse_cao("3\n0 0 0\n1 0 0\n0 1 0\n0\n0\n1\n3 0 1 2\n", "t.cao");
  ASSERT_TRUE(m);
  EXPECT_FALSE(dominant_face_colour(*m).has_value());
  const Model g = with_face_colour(*m, Eigen::Vector3f(0.1f, 0.2f, 0.3f));
  ASSERT_TRUE(dominant_face_colour(g).has_value());
  EXPECT_TRUE(dominant_face_colour(g)->isApprox(Eigen::Vector3f(0.1f, 0.2f, 0.3f)));
  EXPECT_EQ(g.faces().size(), m->faces().size());
  EXPECT_FALSE(m->faces()[0].attr.colour.has_value());  // the original is untouched
}

TEST(ModelColour, TheSpongeInDataIsAGreenBox) {
  auto m = load_cao(std::string(V4R_DATA_DIR) + "/sponge.cao");
  ASSERT_TRUE(m) << m.error().to_string();
  EXPECT_EQ(m->faces().size(), 6u);
  for (const Face& f : m->faces()) {
    ASSERT_TRUE(f.attr.colour.has_value()) << f.attr.name;
    EXPECT_TRUE(f.attr.colour->isApprox(Eigen::Vector3f(0.2f, 0.6f, 0.1f))) << f.attr.name;
  }
  double area = 0.0;
  for (const Face& f : m->faces()) area += face_area(*m, f);
  EXPECT_NEAR(area, 2 * (0.11 * 0.07 + 0.11 * 0.045 + 0.07 * 0.045), 1e-9);
}
