// v4r - robust model-based object tracking. MIT licence.
// AddModel scale= (model units) and AddObject lifetime= parse, format back and reject bad values.
#include <gtest/gtest.h>

#include <string>

#include "v4r/protocol/protocol.hpp"

namespace vp = v4r::protocol;

namespace {

vp::Command command(const std::string& line) {
  const vp::ParseResult r = vp::parse(line);
  EXPECT_TRUE(std::holds_alternative<vp::Command>(r)) << line;
  return std::holds_alternative<vp::Command>(r) ? std::get<vp::Command>(r) : vp::Command{vp::Ping{}};
}

std::string error_code(const std::string& line) {
  const vp::ParseResult r = vp::parse(line);
  return std::holds_alternative<vp::ParseError>(r) ? std::get<vp::ParseError>(r).code : "parsed";
}

}  // namespace

TEST(ProtocolUnits, AddModelScale) {
  const auto path = std::get<vp::AddModelPath>(command("AddModel object=box path=box_mm.obj scale=0.001"));
  EXPECT_EQ(path.scale, 0.001);
  EXPECT_EQ(std::get<vp::AddModelPath>(command("AddModel object=box path=box.obj")).scale, 1.0);
  const auto inl = std::get<vp::AddModelInline>(command("AddModel object=box format=obj scale=0.01 bytes=12"));
  EXPECT_EQ(inl.scale, 0.01);
  EXPECT_EQ(inl.bytes, 12u);
  // Formatted back as it was given (and without scale= at the default).
  EXPECT_EQ(vp::format(vp::Command{path}), "AddModel object=box path=box_mm.obj scale=0.001");
  EXPECT_EQ(std::get<vp::AddModelPath>(command(vp::format(vp::Command{path}))), path);
  EXPECT_EQ(vp::format(vp::Command{inl}), "AddModel object=box format=obj scale=0.01 bytes=12");
  EXPECT_EQ(error_code("AddModel object=box path=b.obj scale=0"), "out_of_range");
  EXPECT_EQ(error_code("AddModel object=box path=b.obj scale=-0.001"), "out_of_range");
  EXPECT_EQ(error_code("AddModel object=box path=b.obj scale=mm"), "bad_number");
}

TEST(ProtocolUnits, AddObjectLifetime) {
  EXPECT_FALSE(std::get<vp::AddObject>(command("AddObject name=box")).connection_lifetime);
  EXPECT_FALSE(std::get<vp::AddObject>(command("AddObject name=box lifetime=server")).connection_lifetime);
  const auto own = std::get<vp::AddObject>(command("AddObject name=box lifetime=connection"));
  EXPECT_TRUE(own.connection_lifetime);
  EXPECT_EQ(vp::format(vp::Command{own}), "AddObject name=box lifetime=connection");
  EXPECT_EQ(error_code("AddObject name=box lifetime=forever"), "bad_argument");
  EXPECT_EQ(error_code("RemoveObject name=box lifetime=connection"), "unknown_argument");
}
