// v4r - robust model-based object tracking. MIT licence.
// Table tests of parse(): every command, valid and invalid lines, exact error codes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "v4r/protocol/protocol.hpp"

namespace vp = v4r::protocol;

namespace {

struct Valid {
  std::string line;
  vp::Command expected;
};

// Valid lines with the command they must give. Numbers are chosen so that the expected doubles
// are exactly what a correctly rounded decimal reader returns.
std::vector<Valid> valid_rows() {
  const std::string name64(64, 'n');
  return {
      {"AddObject name=box", vp::AddObject{"box"}},
      {"AddObject name=a.b-C_9", vp::AddObject{"a.b-C_9"}},
      {"   AddObject    name=box   ", vp::AddObject{"box"}},
      {"AddObject name=box\r", vp::AddObject{"box"}},
      {"AddObject name=\"box\"", vp::AddObject{"box"}},
      {"AddObject name=" + name64, vp::AddObject{name64}},
      {"RemoveObject name=box", vp::RemoveObject{"box"}},
      {"AddModel object=box format=cao bytes=1234", vp::AddModelInline{"box", vp::ModelFormat::kCao, 1234}},
      {"AddModel bytes=1 format=stl object=o", vp::AddModelInline{"o", vp::ModelFormat::kStl, 1}},
      {"AddModel object=box format=obj bytes=16777216", vp::AddModelInline{"box", vp::ModelFormat::kObj, 16777216}},
      {"AddModel object=box format=ply bytes=007", vp::AddModelInline{"box", vp::ModelFormat::kPly, 7}},
      {"AddModel object=box path=/data/box.cao", vp::AddModelPath{"box", "/data/box.cao", std::nullopt}},
      {R"(AddModel object=box path="/data/my models/box \"v2\".cao" format=cao)",
       vp::AddModelPath{"box", "/data/my models/box \"v2\".cao", vp::ModelFormat::kCao}},
      {R"(AddModel object=box path=C:\models\x.ply)", vp::AddModelPath{"box", R"(C:\models\x.ply)", std::nullopt}},
      {"AddFeature object=box type=junction id=J1 p=0.1,-0.2,3e-1", vp::AddJunction{"box", "J1", {0.1, -0.2, 0.3}}},
      {"AddFeature object=box type=junction id=J2 p=+1,.5,5.", vp::AddJunction{"box", "J2", {1.0, 0.5, 5.0}}},
      {"AddFeature object=box type=line id=L1 from=J1 to=J2", vp::AddLine{"box", "L1", "J1", "J2"}},
      {"AddFeature object=cup type=circle id=C1 center=0,0,0.1 normal=0,0,1 radius=0.04",
       vp::AddCircle{"cup", "C1", {0, 0, 0.1}, {0, 0, 1}, 0.04}},
      {"AddFeature type=circle object=cup id=C2 radius=1e-3 normal=0,0,-2 center=1,2,3",
       vp::AddCircle{"cup", "C2", {1, 2, 3}, {0, 0, -2}, 0.001}},
      {"RemoveFeature object=box id=L1", vp::RemoveFeature{"box", "L1"}},
      {"SetPose object=box t=0.01,-0.02,0.5 r=0,3.14159265358979,0",
       vp::SetPose{"box", {0.01, -0.02, 0.5}, {0, 3.14159265358979, 0}}},
      {"SetPose object=box t=-0,0,1e-400 r=1E2,2e+1,-3.5e-3", vp::SetPose{"box", {-0.0, 0, 0}, {100, 20, -0.0035}}},
      {"SetPose object=box t=1e-310,0,1.7976931348623157e308 r=0,0,0",
       vp::SetPose{"box", {1e-310, 0, 1.7976931348623157e308}, {0, 0, 0}}},
      {"Subscribe what=ObjectPose", vp::Subscribe{vp::Topic::kObjectPose, 0.0}},
      {"Subscribe what=SystemStatus rate=2.5", vp::Subscribe{vp::Topic::kSystemStatus, 2.5}},
      {"Subscribe what=ObjectPose rate=-0", vp::Subscribe{vp::Topic::kObjectPose, 0.0}},
      {"Unsubscribe what=SystemStatus", vp::Unsubscribe{vp::Topic::kSystemStatus}},
      {"SetParam name=track.rows value=32", vp::SetParam{"track.rows", "32"}},
      {"SetParam name=track.use_cues value=\"off\"", vp::SetParam{"track.use_cues", "off"}},
      {"SetParam name=edge.mode value=\"a b\"", vp::SetParam{"edge.mode", "a b"}},
      {"SetParam name=x value=a=b", vp::SetParam{"x", "a=b"}},
      {"GetParam name=track.rows", vp::GetParam{"track.rows"}},
      {"ListParams", vp::ListParams{}},
      {"Start", vp::Start{}},
      {"Pause", vp::Pause{}},
      {"Display on", vp::Display{true}},
      {"Display off", vp::Display{false}},
      {"Log on", vp::Log{true, ""}},
      {"Log file=/tmp/cycle.csv on", vp::Log{true, "/tmp/cycle.csv"}},
      {"Log off", vp::Log{false, ""}},
      {"Ping", vp::Ping{}},
      {"Quit\r", vp::Quit{}},
      {"Auth token=s3cr3t", vp::Auth{"s3cr3t"}},
      {R"(Auth token="with space \\ and \" quote")", vp::Auth{R"(with space \ and " quote)"}},
  };
}

struct Invalid {
  std::string line;
  std::string command;   // for ERR <Command>
  std::string code;
  std::string fragment;  // must occur in the message
  std::size_t skip = 0;  // ParseError::skip_bytes
};

std::vector<Invalid> invalid_rows() {
  using std::string;
  return {
      {"", "?", "empty_line", "empty line"},
      {"     ", "?", "empty_line", "empty line"},
      {"\r", "?", "empty_line", "empty line"},
      {"Hello", "Hello", "unknown_command", "unknown command 'Hello'"},
      {"addobject name=box", "addobject", "unknown_command", "did you mean AddObject?"},
      {"ADDOBJECT name=box", "ADDOBJECT", "unknown_command", "case-sensitive"},
      {"name=box", "?", "bad_syntax", "starts with a command name"},
      {"AddObject", "AddObject", "missing_argument", "missing argument name="},
      {"AddObject box", "AddObject", "bad_syntax", "unexpected word 'box'"},
      {"AddObject name=box name=cup", "AddObject", "duplicate_argument", "name= given twice (column 20)"},
      {"AddObject name=box color=red", "AddObject", "unknown_argument", "unknown argument 'color=' for AddObject (takes name= lifetime=)"},
      {"AddObject name=", "AddObject", "bad_syntax", "empty value"},
      {"AddObject name=\"\"", "AddObject", "bad_name", "not a valid name"},
      {"AddObject name=a/b", "AddObject", "bad_name", "'a/b' is not a valid name"},
      {"AddObject name=" + string(65, 'n'), "AddObject", "bad_name", "1 to 64 characters"},
      {"AddObject name=\"a b\"", "AddObject", "bad_name", "'a b'"},
      {"AddObject name=\"box", "AddObject", "bad_syntax", "unterminated quoted value (column 16)"},
      {"AddObject name=\"box\"x", "AddObject", "bad_syntax", "text after the closing quote"},
      {"AddObject name=bo\"x", "AddObject", "bad_syntax", "inside an unquoted value"},
      {"AddObject name=\"b\\ox\"", "AddObject", "bad_syntax", "unknown escape '\\o'"},
      {"AddObject \"box\"", "AddObject", "bad_syntax", "quoted text without a key"},
      {"AddObject =box", "AddObject", "bad_syntax", "'=' without a key"},
      {"AddObject na/me=box", "AddObject", "bad_syntax", "bad character '/' in key 'na/me'"},
      {"AddObject na-me=box", "AddObject", "unknown_argument", "'na-me='"},
      {"AddObject name=box\t", "AddObject", "bad_byte", "byte 0x09 is not printable ASCII (0x20..0x7E) (column 19)"},
      {"AddObject name=b\x01ox", "AddObject", "bad_byte", "byte 0x01 is not printable ASCII (0x20..0x7E) (column 17)"},
      {"AddObject name=bo\xc3\xa9", "AddObject", "bad_byte", "byte 0xC3"},
      {string("AddObject\0name=box", 18), "?", "bad_byte", "byte 0x00 is not printable ASCII (0x20..0x7E) (column 10)"},
      {"AddObject name=box\r\r", "AddObject", "bad_byte", "byte 0x0D"},
      {"AddObject name=box\nRemoveObject name=box", "AddObject", "bad_byte", "byte 0x0A"},
      {"AddModel object=box format=cao", "AddModel", "missing_argument", "bytes= (the model text follows) or path="},
      {"AddModel object=box bytes=10", "AddModel", "missing_argument", "missing argument format=", 10},
      {"AddModel object=box format=dxf bytes=10", "AddModel", "bad_argument", "'dxf' is not one of cao|obj|ply|stl", 10},
      {"AddModel object=box format=cao bytes=0", "AddModel", "out_of_range", "at least 1"},
      {"AddModel object=box format=cao bytes=16777217", "AddModel", "too_large", "beyond the limit of 16777216 bytes"},
      {"AddModel object=box format=cao bytes=-5", "AddModel", "bad_number", "'-5' is not a whole number"},
      {"AddModel object=box format=cao bytes=99999999999999999999999", "AddModel", "bad_number", "does not fit in 64 bits"},
      {"AddModel object=box format=cao bytes=12 path=/x.cao", "AddModel", "bad_argument", "not both", 12},
      {"AddModel object=b@x format=cao bytes=12", "AddModel", "bad_name", "'b@x'", 12},
      {"AddModel format=cao bytes=12", "AddModel", "missing_argument", "missing argument object=", 12},
      {"AddModel object=\"box format=cao bytes=12", "AddModel", "bad_syntax", "unterminated", 12},
      {"AddModel object=box path=\"\"", "AddModel", "bad_argument", "path=: must not be empty"},
      {"AddFeature object=box id=J1 p=1,2,3", "AddFeature", "missing_argument", "missing argument type="},
      {"AddFeature object=box type=point id=J1 p=1,2,3", "AddFeature", "bad_argument", "is not one of junction|line|circle"},
      {"AddFeature object=box type=junction id=J1 p=1,2", "AddFeature", "bad_vector",
       "p=: expected 3 comma-separated numbers x,y,z, got 2 (column 45)"},
      {"AddFeature object=box type=junction id=J1 p=1,2,3,4", "AddFeature", "bad_vector", "got 4"},
      {"AddFeature object=box type=junction id=J1 p=1,,3", "AddFeature", "bad_number", "p=: component 2 is empty (column 47)"},
      {"AddFeature object=box type=junction id=J1 p=1,x,3", "AddFeature", "bad_number", "component 2 'x' is not a number"},
      {"AddFeature object=box type=junction id=J1 p=nan,0,0", "AddFeature", "not_finite", "'nan' is not a finite number"},
      {"AddFeature object=box type=junction id=J1 p=0,-Inf,0", "AddFeature", "not_finite", "component 2 '-Inf'"},
      {"AddFeature object=box type=junction id=J1 p=0,0,1e309", "AddFeature", "not_finite", "'1e309'"},
      {"AddFeature object=box type=junction id=J1 p=0,0,-123456789e305", "AddFeature", "not_finite", "component 3"},
      {"AddFeature object=box type=junction id=J1 p=0,0,1e3x", "AddFeature", "bad_number", "'1e3x' is not a number"},
      {"AddFeature object=box type=junction id=J1 p=0x10,0,0", "AddFeature", "bad_number", "'0x10'"},
      {"AddFeature object=box type=junction id=J1 p=1,2,3 radius=2", "AddFeature", "unknown_argument",
       "'radius=' for AddFeature (takes object= type= id= p=)"},
      {"AddFeature object=box type=junction id=J1", "AddFeature", "missing_argument", "missing argument p="},
      {"AddFeature object=box type=line id=L1 from=J1", "AddFeature", "missing_argument", "missing argument to="},
      {"AddFeature object=box type=line id=L1 from=J1 to=J1", "AddFeature", "bad_argument", "same junction 'J1'"},
      {"AddFeature object=cup type=circle id=C center=0,0,0 normal=0,0,0 radius=1", "AddFeature", "out_of_range",
       "normal=: must not be the zero vector"},
      {"AddFeature object=cup type=circle id=C center=0,0,0 normal=0,0,1 radius=0", "AddFeature", "out_of_range",
       "radius=: must be > 0"},
      {"AddFeature object=cup type=circle id=C center=0,0,0 normal=0,0,1 radius=-1", "AddFeature", "out_of_range",
       "radius="},
      {"AddFeature object=cup type=circle id=C center=0,0 normal=0,0,1 radius=1", "AddFeature", "bad_vector",
       "center=: expected 3"},
      {"RemoveFeature object=box", "RemoveFeature", "missing_argument", "missing argument id="},
      {"SetPose object=box t=0,0,1", "SetPose", "missing_argument", "missing argument r="},
      {"SetPose object=box t=0,0,1 r=0,0,NaN", "SetPose", "not_finite", "r=: component 3 'NaN'"},
      {"SetPose object=box t=0,0,1 r=0,0,0 q=1,0,0,0", "SetPose", "unknown_argument", "'q='"},
      {"SetPose object=box t=0;0;1 r=0,0,0", "SetPose", "bad_vector", "t=: expected 3 comma-separated numbers tx,ty,tz, got 1"},
      {"Subscribe", "Subscribe", "missing_argument", "missing argument what="},
      {"Subscribe what=objectpose", "Subscribe", "bad_argument", "is not one of ObjectPose|SystemStatus"},
      {"Subscribe what=ObjectPose rate=-1", "Subscribe", "out_of_range", "rate=: must be >= 0 Hz"},
      {"Subscribe what=ObjectPose rate=fast", "Subscribe", "bad_number", "'fast' is not a number"},
      {"Subscribe what=ObjectPose rate=inf", "Subscribe", "not_finite", "rate="},
      {"Unsubscribe what=ObjectPose rate=1", "Unsubscribe", "unknown_argument", "(takes what=)"},
      {"SetParam name=track.rows", "SetParam", "missing_argument", "missing argument value="},
      {"SetParam name=track.rows value=\"\"", "SetParam", "bad_argument", "value=: must not be empty"},
      {"SetParam value=3", "SetParam", "missing_argument", "missing argument name="},
      {"GetParam name=track rows", "GetParam", "bad_syntax", "unexpected word 'rows' (arguments are key=value)"},
      {"ListParams all", "ListParams", "bad_syntax", "unexpected word 'all'"},
      {"Ping x=1", "Ping", "unknown_argument", "(takes none)"},
      {"Quit now", "Quit", "bad_syntax", "unexpected word 'now'"},
      {"Display", "Display", "missing_argument", "missing on or off"},
      {"Display yes", "Display", "bad_argument", "'yes' is not on|off"},
      {"Display on off", "Display", "bad_syntax", "unexpected word 'off'"},
      {"Log off file=x.csv", "Log", "bad_argument", "file= goes with Log on only"},
      {"Log on file=", "Log", "bad_syntax", "empty value"},
      {"Auth", "Auth", "missing_argument", "missing argument token="},
      {"Auth token=\"\"", "Auth", "bad_argument", "token=: must not be empty"},
      {"AddObject name=box" + string(5000, ' '), "AddObject", "too_long",
       "line of 5018 bytes is longer than the limit of 4096"},
  };
}

std::string describe(const vp::ParseResult& r) {
  if (const auto* e = std::get_if<vp::ParseError>(&r)) return "ParseError " + e->code + ": " + e->message;
  return "Command " + vp::format(std::get<vp::Command>(r));
}

}  // namespace

TEST(ProtocolParse, ValidLinesGiveTheirCommand) {
  const auto rows = valid_rows();
  for (const Valid& row : rows) {
    SCOPED_TRACE(row.line);
    const vp::ParseResult r = vp::parse(row.line);
    ASSERT_TRUE(std::holds_alternative<vp::Command>(r)) << describe(r);
    EXPECT_EQ(std::get<vp::Command>(r), row.expected) << describe(r);
  }
}

TEST(ProtocolParse, InvalidLinesGiveExactCodes) {
  const auto rows = invalid_rows();
  for (const Invalid& row : rows) {
    SCOPED_TRACE(row.line.substr(0, 100));
    const vp::ParseResult r = vp::parse(row.line);
    ASSERT_TRUE(std::holds_alternative<vp::ParseError>(r)) << describe(r);
    const auto& e = std::get<vp::ParseError>(r);
    EXPECT_EQ(e.code, row.code) << e.message;
    EXPECT_EQ(e.command, row.command);
    EXPECT_NE(e.message.find(row.fragment), std::string::npos) << "message: " << e.message;
    EXPECT_EQ(e.skip_bytes, row.skip);
  }
}

TEST(ProtocolParse, TableIsLargeEnough) { EXPECT_GE(valid_rows().size() + invalid_rows().size(), 60u); }

TEST(ProtocolParse, NegativeZeroAndSubnormalKeepTheirBits) {
  const auto r = vp::parse("SetPose object=box t=-0,4.9e-324,1e-400 r=-1e-400,0,0");
  ASSERT_TRUE(std::holds_alternative<vp::Command>(r)) << describe(r);
  const auto& p = std::get<vp::SetPose>(std::get<vp::Command>(r));
  EXPECT_TRUE(std::signbit(p.t[0]));
  EXPECT_EQ(p.t[1], 4.9e-324);
  EXPECT_GT(p.t[1], 0.0);
  EXPECT_EQ(p.t[2], 0.0);
  EXPECT_TRUE(std::signbit(p.r[0]));  // underflow keeps the sign
}

TEST(ProtocolParse, LineLimitIsInclusive) {
  std::string line = "AddModel object=box path=/";
  line += std::string(vp::kMaxLineBytes - line.size(), 'p');
  ASSERT_EQ(line.size(), vp::kMaxLineBytes);
  auto r = vp::parse(line);
  ASSERT_TRUE(std::holds_alternative<vp::Command>(r)) << describe(r);
  EXPECT_EQ(std::get<vp::AddModelPath>(std::get<vp::Command>(r)).path.size(), vp::kMaxLineBytes - 25);
  r = vp::parse(line + "\r");  // CR does not count
  EXPECT_TRUE(std::holds_alternative<vp::Command>(r)) << describe(r);
  r = vp::parse(line + "p");
  ASSERT_TRUE(std::holds_alternative<vp::ParseError>(r));
  EXPECT_EQ(std::get<vp::ParseError>(r).code, "too_long");
  EXPECT_EQ(std::get<vp::ParseError>(r).command, "AddModel");
}

TEST(ProtocolParse, ColumnsPointAtTheProblem) {
  struct Row {
    const char* line;
    std::size_t column;
  };
  for (const Row& row : {Row{"AddObject name=b\x01ox", 17}, Row{"AddObject name=box name=cup", 20},
                         Row{"AddObject name=a/b", 16}, Row{"Ping x=1", 6},
                         Row{"AddFeature object=box type=junction id=J1 p=1,2,3x", 49}, Row{"Bogus", 1}}) {
    SCOPED_TRACE(row.line);
    const auto r = vp::parse(row.line);
    ASSERT_TRUE(std::holds_alternative<vp::ParseError>(r));
    EXPECT_EQ(std::get<vp::ParseError>(r).column, row.column) << std::get<vp::ParseError>(r).message;
  }
}

TEST(ProtocolParse, BlankLines) {
  EXPECT_TRUE(vp::is_blank(""));
  EXPECT_TRUE(vp::is_blank("   "));
  EXPECT_TRUE(vp::is_blank("\r"));
  EXPECT_TRUE(vp::is_blank("  \r"));
  EXPECT_FALSE(vp::is_blank("\t"));
  EXPECT_FALSE(vp::is_blank(" Ping"));
  EXPECT_FALSE(vp::is_blank("\r\r"));
}

TEST(ProtocolFormat, EveryValidCommandRoundTrips) {
  for (const Valid& row : valid_rows()) {
    const std::string text = vp::format(row.expected);
    SCOPED_TRACE(text);
    const auto r = vp::parse(text);
    ASSERT_TRUE(std::holds_alternative<vp::Command>(r)) << describe(r);
    EXPECT_EQ(std::get<vp::Command>(r), row.expected);
    EXPECT_EQ(vp::command_name(std::get<vp::Command>(r)), text.substr(0, text.find(' ')));
    // Formatting is canonical: a second round gives the same text.
    EXPECT_EQ(vp::format(std::get<vp::Command>(r)), text);
  }
}

TEST(ProtocolFormat, CanonicalText) {
  EXPECT_EQ(vp::format(vp::AddModelInline{"box", vp::ModelFormat::kPly, 7}), "AddModel object=box format=ply bytes=7");
  EXPECT_EQ(vp::format(vp::AddModelPath{"box", "my dir/a.cao", std::nullopt}), R"(AddModel object=box path="my dir/a.cao")");
  EXPECT_EQ(vp::format(vp::AddJunction{"box", "J1", {0.1, -0.0, 1e21}}), "AddFeature object=box type=junction id=J1 p=0.1,-0,1e+21");
  EXPECT_EQ(vp::format(vp::AddCircle{"c", "C", {0, 0, 0.1}, {0, 0, 1}, 0.04}),
            "AddFeature object=c type=circle id=C center=0,0,0.1 normal=0,0,1 radius=0.04");
  EXPECT_EQ(vp::format(vp::SetPose{"box", {1.0 / 3.0, 0, 0}, {0, 0, 0}}),
            "SetPose object=box t=0.3333333333333333,0,0 r=0,0,0");
  EXPECT_EQ(vp::format(vp::Subscribe{vp::Topic::kSystemStatus, 0}), "Subscribe what=SystemStatus");
  EXPECT_EQ(vp::format(vp::Subscribe{vp::Topic::kObjectPose, 30}), "Subscribe what=ObjectPose rate=30");
  EXPECT_EQ(vp::format(vp::Log{true, "a.csv"}), "Log on file=a.csv");
  EXPECT_EQ(vp::format(vp::Display{false}), "Display off");
  EXPECT_EQ(vp::format(vp::Auth{R"(a"b\c)"}), R"(Auth token="a\"b\\c")");
  EXPECT_EQ(vp::payload_bytes(vp::AddModelInline{"box", vp::ModelFormat::kCao, 99}), 99u);
  EXPECT_EQ(vp::payload_bytes(vp::Ping{}), 0u);
}

TEST(ProtocolFormat, NumbersAreShortestRoundTrip) {
  EXPECT_EQ(vp::format_number(0.1), "0.1");
  EXPECT_EQ(vp::format_number(1.0), "1");
  EXPECT_EQ(vp::format_number(-0.0), "-0");
  EXPECT_EQ(vp::format_number(1e-7), "1e-07");
  EXPECT_EQ(vp::format_number(5e-324), "5e-324");
  EXPECT_EQ(vp::format_number(1.7976931348623157e308), "1.7976931348623157e+308");
  EXPECT_EQ(vp::format_number(std::nan("")), "nan");
  EXPECT_EQ(vp::format_number(-INFINITY), "-inf");
}

TEST(ProtocolFormat, QuotingAndValues) {
  EXPECT_EQ(vp::quote(""), "\"\"");
  EXPECT_EQ(vp::quote(R"(say "hi" \ now)"), R"("say \"hi\" \\ now")");
  EXPECT_EQ(vp::quote("line\nbreak\x7f"), "\"line?break?\"");
  EXPECT_EQ(vp::format_value("plain.value"), "plain.value");
  EXPECT_EQ(vp::format_value("two words"), "\"two words\"");
  EXPECT_EQ(vp::format_value(""), "\"\"");
  EXPECT_EQ(vp::format_value("a\"b"), R"("a\"b")");
  EXPECT_TRUE(vp::is_valid_name("Box_1.v-2"));
  EXPECT_FALSE(vp::is_valid_name(""));
  EXPECT_FALSE(vp::is_valid_name("a b"));
  EXPECT_FALSE(vp::is_valid_name(std::string(65, 'a')));
}
