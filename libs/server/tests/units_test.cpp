// v4r - robust model-based object tracking. MIT licence.
// Unit tests of the server's pure parts: the feature-by-feature model and the client outbox.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include "v4r/model/cao_reader.hpp"
#include "v4r/server/feature_model.hpp"
#include "v4r/server/outbox.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::server {
namespace {

SharedLine line(const std::string& s) { return std::make_shared<const std::string>(s); }

std::vector<std::string> texts(const std::vector<SharedLine>& v) {
  std::vector<std::string> out;
  for (const auto& l : v) out.push_back(*l);
  return out;
}

TEST(Outbox, RepliesKeepTheirOrderAndEventsKeepOnlyTheNewestPerKey) {
  Outbox box(8);
  EXPECT_TRUE(box.empty());
  box.put_event("P a", line("a0"));
  box.put_event("P b", line("b0"));
  ASSERT_TRUE(box.push_reply(line("r0")));
  box.put_event("P a", line("a1"));  // replaces a0
  box.put_event("S", line("s1"));
  ASSERT_TRUE(box.push_reply(line("r1")));
  box.put_event("P a", line("a2"));  // replaces a1
  std::vector<SharedLine> out;
  EXPECT_EQ(box.take(out), 5u);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"r0", "r1", "a2", "b0", "s1"}));
  EXPECT_EQ(box.events_replaced(), 2u);
  EXPECT_TRUE(box.empty());
  out.clear();
  EXPECT_EQ(box.take(out), 0u);
  // After a take, the slots are free again: a new event is kept, not counted as replaced.
  box.put_event("P b", line("b1"));
  EXPECT_FALSE(box.empty());
  EXPECT_EQ(box.take(out), 1u);
  EXPECT_EQ(*out[0], "b1");
  EXPECT_EQ(box.events_replaced(), 2u);
}

TEST(Outbox, ReplyQueueIsBoundedAndEventsStayBoundedUnderAFlood) {
  Outbox box(4);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(box.push_reply(line("r")));
  EXPECT_FALSE(box.push_reply(line("overflow")));
  EXPECT_EQ(box.replies_waiting(), 4u);
  // A thousand frames for three objects while nothing is sent: three slots plus the status.
  for (int f = 0; f < 1000; ++f) {
    for (const char* o : {"P a", "P b", "P c"}) box.put_event(o, line(std::to_string(f)));
    box.put_event("S", line(fmt::format("s{}", f)));
  }
  std::vector<SharedLine> out;
  EXPECT_EQ(box.take(out), 4u + 4u);
  EXPECT_EQ(*out[4], "999");
  EXPECT_EQ(*out[7], "s999");
  EXPECT_EQ(box.events_replaced(), 4u * 999u);
}

TEST(Outbox, WithADepthABriefBacklogKeepsEveryEventInFrameOrder) {
  Outbox box(4, 3);
  for (int f = 0; f < 3; ++f) {
    box.put_event("P a", line(fmt::format("a{}", f)));
    box.put_event("S", line(fmt::format("s{}", f)));
  }
  std::vector<SharedLine> out;
  EXPECT_EQ(box.take(out), 6u);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"a0", "s0", "a1", "s1", "a2", "s2"}));
  EXPECT_EQ(box.events_replaced(), 0u);
  // Further behind than the depth: the oldest go, the newest three per key stay.
  for (int f = 0; f < 10; ++f) box.put_event("P a", line(fmt::format("a{}", f)));
  out.clear();
  EXPECT_EQ(box.take(out), 3u);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"a7", "a8", "a9"}));
  EXPECT_EQ(box.events_replaced(), 7u);
}

TEST(Outbox, UnsubscribeDropsOnlyThatTopic) {
  Outbox box(4);
  box.put_event("P a", line("a"));
  box.put_event("S", line("s"));
  box.drop_events("P ");
  std::vector<SharedLine> out;
  box.take(out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"s"}));
}

TEST(FeatureModel, RebuildsTheShipFromItsJunctionsAndLines) {
  auto ship = model::parse_cao(synth::ship_mockup_cao(), "ship");
  ASSERT_TRUE(ship) << ship.error().to_string();
  FeatureModel fm;
  EXPECT_FALSE(fm.trackable());
  for (std::size_t i = 0; i < ship->junctions().size(); ++i)
    ASSERT_TRUE(fm.add_junction(fmt::format("j{}", i), ship->junctions()[i].p));
  EXPECT_FALSE(fm.trackable());
  for (std::size_t i = 0; i < ship->lines().size(); ++i) {
    const auto& l = ship->lines()[i];
    ASSERT_TRUE(fm.add_line(fmt::format("l{}", i), fmt::format("j{}", l.a), fmt::format("j{}", l.b)));
  }
  ASSERT_TRUE(fm.trackable());
  auto m = fm.build("ship");
  ASSERT_TRUE(m) << m.error().to_string();
  ASSERT_EQ((*m)->lines().size(), ship->lines().size());
  ASSERT_EQ((*m)->junctions().size(), ship->junctions().size());
  EXPECT_TRUE((*m)->faces().empty());
  for (std::size_t i = 0; i < ship->lines().size(); ++i) {
    EXPECT_LT(((*m)->line_point_a(i) - ship->line_point_a(i)).norm(), 1e-12);
    EXPECT_LT(((*m)->line_point_b(i) - ship->line_point_b(i)).norm(), 1e-12);
    EXPECT_EQ((*m)->lines()[i].face_left, model::kNone);
  }
  EXPECT_NEAR((*m)->bounding_radius(), ship->bounding_radius(), 1e-12);
}

TEST(FeatureModel, RejectsDuplicatesDanglingReferencesAndDegenerateFeatures) {
  FeatureModel fm;
  ASSERT_TRUE(fm.add_junction("a", {0, 0, 0}));
  ASSERT_TRUE(fm.add_junction("b", {0.1, 0, 0}));
  ASSERT_TRUE(fm.add_junction("c", {0, 0, 0}));  // same place as a: allowed, but no line a-c
  auto dup = fm.add_junction("a", {1, 1, 1});
  ASSERT_FALSE(dup);
  EXPECT_EQ(dup.error().field, "exists");
  auto dangling = fm.add_line("l", "a", "zz");
  ASSERT_FALSE(dangling);
  EXPECT_EQ(dangling.error().field, "not_found");
  EXPECT_FALSE(fm.add_line("l", "a", "a"));
  EXPECT_FALSE(fm.add_line("l", "a", "c"));
  EXPECT_FALSE(fm.add_junction("n", {std::nan(""), 0, 0}));
  ASSERT_TRUE(fm.add_line("l", "a", "b"));
  EXPECT_EQ(fm.add_line("l", "b", "c").error().field, "exists");
  EXPECT_FALSE(fm.add_circle("c1", {0, 0, 0}, {0, 0, 0}, 0.1));
  EXPECT_FALSE(fm.add_circle("c1", {0, 0, 0}, {0, 0, 1}, -0.1));
  ASSERT_TRUE(fm.add_circle("c1", {0, 0, 0.05}, {0, 0, 2}, 0.04));
  // A junction used by a line stays until the line goes.
  auto in_use = fm.remove("a");
  ASSERT_FALSE(in_use);
  EXPECT_EQ(in_use.error().field, "in_use");
  EXPECT_EQ(fm.remove("nope").error().field, "not_found");
  auto m = fm.build("x");
  ASSERT_TRUE(m);
  EXPECT_EQ((*m)->lines().size(), 1u);
  ASSERT_EQ((*m)->arcs().size(), 1u);
  EXPECT_NEAR((*m)->arcs()[0].normal.norm(), 1.0, 1e-12);
  EXPECT_NEAR((*m)->arcs()[0].radius, 0.04, 1e-15);
  ASSERT_TRUE(fm.remove("l"));
  ASSERT_TRUE(fm.remove("a"));
  ASSERT_TRUE(fm.remove("c1"));
  EXPECT_FALSE(fm.trackable());
  EXPECT_EQ(fm.junction_count(), 2u);
}

}  // namespace
}  // namespace v4r::server
