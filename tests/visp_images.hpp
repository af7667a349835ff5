// v4r - robust model-based object tracking. MIT licence.
// Where the tests find ViSP's images (Debian visp-images-data), and the skip-or-fail rule.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace {

/// ViSP's test images: $VISP_INPUT_IMAGE_PATH (with or without the ViSP-images suffix), else
/// where Debian's visp-images-data installs them. Empty if absent.
std::filesystem::path visp_images() {
  if (const char* env = std::getenv("VISP_INPUT_IMAGE_PATH"); env != nullptr && *env != '\0') {
    std::filesystem::path p(env);
    if (p.filename() != "ViSP-images") p /= "ViSP-images";
    if (std::filesystem::is_directory(p)) return p;
  }
  const std::filesystem::path debian = "/usr/share/visp-images-data/ViSP-images";
  return std::filesystem::is_directory(debian) ? debian : std::filesystem::path{};
}

bool required() {
  const char* env = std::getenv("V4R_REQUIRE_VISP_IMAGES");
  return env != nullptr && *env != '\0' && std::string(env) != "0";
}

#define V4R_NEED_VISP_IMAGES(root)                                                                          \
  do {                                                                                                      \
    if ((root).empty()) {                                                                                   \
      if (required()) FAIL() << "V4R_REQUIRE_VISP_IMAGES is set but ViSP-images is missing "                \
                                "(apt-get install visp-images-data, or set VISP_INPUT_IMAGE_PATH)";         \
      GTEST_SKIP() << "visp-images-data is not installed (apt-get install visp-images-data; `make test` "    \
                      "installs it and sets V4R_REQUIRE_VISP_IMAGES=1)";                                    \
    }                                                                                                       \
  } while (0)

}  // namespace
