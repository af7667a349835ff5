// v4r - robust model-based object tracking. MIT licence.
// libFuzzer target for the .cao reader (issue 4): AddModel format=cao hands client bytes to
// v4r::model::parse_cao, so any bytes must give a Model or an Error, never a crash, a hang or a
// sanitizer report. The source name points into a directory that does not exist, so relative
// load("...") includes fail instead of reading files.
#include <cstdint>
#include <string>

#include "v4r/model/cao_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const auto model = v4r::model::parse_cao(text, "/nonexistent-v4r-fuzz/input.cao");
  if (!model) (void)model.error().to_string();
  return 0;
}
