// v4r - robust model-based object tracking. MIT licence.
//
// Frame sources: a folder of images, a printf-style file pattern, a single image or a video
// (live cameras: live_source.cpp).
//
// Decoding: images are read with IMREAD_ANYDEPTH | IMREAD_ANYCOLOR (EXIF orientation applied),
// so grey images stay 1-channel and colour images are 3-channel BGR; an alpha channel is
// dropped. Every frame handed out is 8-bit: 16-bit images are scaled by 255/65535 (signed 16-bit
// by 255/32767, negatives clipped), float images are assumed to lie in [0, 1]. A frame that
// cannot be decoded is reported as an Error naming the file, and the source moves past it, so
// the caller may skip it and call next() again.

#include "v4r/io/frame_source.hpp"

#include "live_source.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <opencv2/videoio/registry.hpp>
#include <mutex>
#include <optional>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

namespace v4r::io {
namespace {

namespace fs = std::filesystem;

/// Upper bound on the frames a pattern may enumerate (guards against a runaway scan).
constexpr int kMaxPatternFrames = 100'000'000;

constexpr std::array<std::string_view, 8> kImageExtensions{".png", ".jpg",  ".jpeg", ".bmp",
                                                           ".tif", ".tiff", ".pgm",  ".ppm"};

std::string lower(std::string s) {
  for (char& c : s) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return s;
}

bool is_image_file(const fs::path& p) {
  const std::string ext = lower(p.extension().string());
  return std::find(kImageExtensions.begin(), kImageExtensions.end(), ext) != kImageExtensions.end();
}

/// Converts a decoded image to 8 bits per channel, 1 or 3 channels (see the file comment).
cv::Mat to_8bit_grey_or_bgr(const cv::Mat& img) {
  cv::Mat out;
  switch (img.depth()) {
    case CV_8U:
      out = img;
      break;
    case CV_16U:
      img.convertTo(out, CV_8U, 255.0 / 65535.0);
      break;
    case CV_16S:
      img.convertTo(out, CV_8U, 255.0 / 32767.0);
      break;
    case CV_32F:
    case CV_64F:
      img.convertTo(out, CV_8U, 255.0);
      break;
    default:
      img.convertTo(out, CV_8U);
      break;
  }
  if (out.channels() == 4) {
    cv::Mat bgr;
    cv::cvtColor(out, bgr, cv::COLOR_BGRA2BGR);
    return bgr;
  }
  if (out.channels() == 2) {  // grey + alpha
    cv::Mat grey;
    cv::extractChannel(out, grey, 0);
    return grey;
  }
  return out;
}

/// \brief A printf integer pattern such as `frames/%06d.png`: one %d/%i/%u conversion with
/// optional flags (-+ 0#), width, precision and length modifier; "%%" is a literal percent.
class Pattern {
 public:
  static std::optional<Pattern> parse(const std::string& s) {
    Pattern p;
    bool found = false;
    std::string* part = &p.prefix_;
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (s[i] != '%') {
        part->push_back(s[i]);
        continue;
      }
      if (i + 1 < s.size() && s[i + 1] == '%') {
        part->push_back('%');
        ++i;
        continue;
      }
      if (found) return std::nullopt;  // a second conversion: not ours to interpret
      std::size_t j = i + 1;
      for (; j < s.size() && std::string_view("-+ 0#").find(s[j]) != std::string_view::npos; ++j) {
        if (s[j] == '-') p.left_ = true;
        if (s[j] == '+') p.plus_ = true;
        if (s[j] == ' ') p.space_ = true;
        if (s[j] == '0') p.zero_ = true;
      }
      std::size_t digits_start = j;
      while (j < s.size() && s[j] >= '0' && s[j] <= '9') ++j;
      if (j - digits_start > 4) return std::nullopt;
      if (j > digits_start) p.width_ = std::atoi(s.substr(digits_start, j - digits_start).c_str());
      if (j < s.size() && s[j] == '.') {
        ++j;
        digits_start = j;
        while (j < s.size() && s[j] >= '0' && s[j] <= '9') ++j;
        if (j - digits_start > 4) return std::nullopt;
        p.precision_ = j > digits_start ? std::atoi(s.substr(digits_start, j - digits_start).c_str()) : 0;
      }
      while (j < s.size() && std::string_view("hljzt").find(s[j]) != std::string_view::npos) ++j;
      if (j >= s.size() || std::string_view("diu").find(s[j]) == std::string_view::npos) return std::nullopt;
      found = true;
      part = &p.suffix_;
      i = j;
    }
    if (!found) return std::nullopt;
    return p;
  }

  /// The file name for index i (i >= 0), as printf would format it.
  [[nodiscard]] std::string operator()(int i) const {
    std::string digits = std::to_string(i);
    if (precision_ >= 0 && static_cast<int>(digits.size()) < precision_) {
      digits.insert(0, static_cast<std::size_t>(precision_) - digits.size(), '0');
    }
    const std::string sign = plus_ ? "+" : space_ ? " " : "";
    std::string body = sign + digits;
    if (static_cast<int>(body.size()) < width_) {
      const std::size_t pad = static_cast<std::size_t>(width_) - body.size();
      if (left_) {
        body.append(pad, ' ');
      } else if (zero_ && precision_ < 0) {
        body = sign + std::string(pad, '0') + digits;
      } else {
        body.insert(0, pad, ' ');
      }
    }
    return prefix_ + body + suffix_;
  }

 private:
  std::string prefix_, suffix_;
  bool left_ = false, plus_ = false, space_ = false, zero_ = false;
  int width_ = 0;
  int precision_ = -1;
};

bool is_file(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

/// \brief Frames from a fixed list of image files (folder, pattern or single image).
class FileListSource final : public FrameSource {
 public:
  explicit FileListSource(std::vector<std::string> files) : files_(std::move(files)) {}

  Expected<bool> next(cv::Mat& bgr) override {
    if (index_ >= files_.size()) return false;
    name_ = files_[index_++];
    cv::Mat img;
    try {
      img = cv::imread(name_, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
    } catch (const cv::Exception& e) {
      return Error{fmt::format("cannot decode image {}: {}", name_, e.what()), name_, 0, 0, {}};
    }
    if (img.empty()) {
      std::error_code ec;
      const char* why = fs::exists(name_, ec) ? "cannot decode image" : "image file disappeared";
      return Error{fmt::format("{} {}", why, name_), name_, 0, 0, {}};
    }
    bgr = to_8bit_grey_or_bgr(img);
    return true;
  }
  [[nodiscard]] std::string current_name() const override { return name_; }
  [[nodiscard]] int size_hint() const override { return static_cast<int>(files_.size()); }
  [[nodiscard]] double file_time_s() const override {
    std::error_code ec;
    const fs::file_time_type t = fs::last_write_time(name_, ec);
    if (ec) return -1.0;
    const auto since = std::chrono::duration_cast<std::chrono::nanoseconds>(
        std::chrono::file_clock::to_sys(t).time_since_epoch());
    return static_cast<double>(since.count()) * 1e-9;
  }

 private:
  std::vector<std::string> files_;
  std::size_t index_ = 0;
  std::string name_;
};

/// \brief Frames decoded by cv::VideoCapture; names are "<path>#<index>" (0-based).
class VideoSource final : public FrameSource {
 public:
  VideoSource(std::unique_ptr<cv::VideoCapture> cap, std::string path) : cap_(std::move(cap)), path_(std::move(path)) {
    const double n = cap_->get(cv::CAP_PROP_FRAME_COUNT);
    count_ = (n > 0.0 && n < 1e9) ? static_cast<int>(n) : -1;
    const double fps = cap_->get(cv::CAP_PROP_FPS);
    fps_ = (std::isfinite(fps) && fps > 0.0 && fps <= 10000.0) ? fps : 0.0;
  }

  Expected<bool> next(cv::Mat& bgr) override {
    if (ended_) return false;
    cv::Mat frame;
    try {
      if (!cap_->read(frame) || frame.empty()) {
        ended_ = true;
        return false;
      }
    } catch (const cv::Exception& e) {
      ended_ = true;
      return Error{fmt::format("cannot decode frame {} of {}: {}", index_, path_, e.what()), path_, 0, 0, {}};
    }
    name_ = fmt::format("{}#{}", path_, index_++);
    bgr = to_8bit_grey_or_bgr(frame);
    return true;
  }
  [[nodiscard]] std::string current_name() const override { return name_; }
  [[nodiscard]] int size_hint() const override { return count_; }
  [[nodiscard]] double nominal_fps() const override { return fps_; }

 private:
  std::unique_ptr<cv::VideoCapture> cap_;
  double fps_ = 0.0;
  std::string path_;
  std::string name_;
  int index_ = 0;
  int count_ = -1;
  bool ended_ = false;
};

/// \brief Video back-ends to try, in order: FFmpeg and OpenCV's own MJPEG reader, which fail
/// quietly on files they cannot read. Only when this OpenCV build has no FFmpeg are the other
/// stream back-ends (GStreamer...) tried as well; those log to stderr through OpenCV on failure.
/// CAP_IMAGES is never used: image sequences are handled above, and it would misread a single
/// file as a sequence.
std::vector<cv::VideoCaptureAPIs> video_backends() {
  std::vector<cv::VideoCaptureAPIs> order;
  const std::vector<cv::VideoCaptureAPIs> available = cv::videoio_registry::getStreamBackends();
  const auto has = [&](cv::VideoCaptureAPIs api) {
    return std::find(available.begin(), available.end(), api) != available.end();
  };
  for (const cv::VideoCaptureAPIs preferred : {cv::CAP_FFMPEG, cv::CAP_OPENCV_MJPEG}) {
    if (has(preferred)) order.push_back(preferred);
  }
  if (has(cv::CAP_FFMPEG)) return order;
  for (const cv::VideoCaptureAPIs api : available) {
    if (api != cv::CAP_IMAGES && std::find(order.begin(), order.end(), api) == order.end()) order.push_back(api);
  }
  if (order.empty()) order.push_back(cv::CAP_ANY);
  return order;
}

Expected<std::unique_ptr<FrameSource>> open_directory(const std::string& dir) {
  std::vector<std::string> files;
  std::error_code ec;
  fs::directory_iterator it(dir, ec);
  if (ec) return Error{fmt::format("cannot list {}: {}", dir, ec.message()), dir, 0, 0, {}};
  for (const fs::directory_entry& e : it) {
    std::error_code fec;
    if (!e.is_regular_file(fec) || !is_image_file(e.path())) continue;
    files.push_back(e.path().string());
  }
  if (files.empty()) return Error{fmt::format("no images in {}", dir), dir, 0, 0, {}};
  std::sort(files.begin(), files.end(), [](const std::string& a, const std::string& b) {
    return fs::path(a).filename().string() < fs::path(b).filename().string();
  });
  return std::unique_ptr<FrameSource>(std::make_unique<FileListSource>(std::move(files)));
}

Expected<std::unique_ptr<FrameSource>> open_pattern(const std::string& input, const Pattern& pattern) {
  int first = 0;
  if (!is_file(pattern(0))) {
    if (!is_file(pattern(1))) {
      return Error{
          fmt::format("no files match {} (neither {} nor {} exists)", input, pattern(0), pattern(1)), input, 0, 0, {}};
    }
    first = 1;
  }
  std::vector<std::string> files;
  for (int i = first; i < kMaxPatternFrames; ++i) {
    std::string name = pattern(i);
    if (!is_file(name)) break;
    files.push_back(std::move(name));
  }
  return std::unique_ptr<FrameSource>(std::make_unique<FileListSource>(std::move(files)));
}

}  // namespace

namespace {

struct Scheme {
  std::string prefix;
  FrameSource::Opener opener;
};

std::mutex& schemes_mutex() {
  static std::mutex m;
  return m;
}

std::vector<Scheme>& schemes() {
  static std::vector<Scheme> s;
  return s;
}

}  // namespace

void FrameSource::register_scheme(const std::string& prefix, Opener opener) {
  std::scoped_lock lock(schemes_mutex());
  for (Scheme& s : schemes()) {
    if (s.prefix == prefix) {
      s.opener = std::move(opener);
      return;
    }
  }
  schemes().push_back(Scheme{prefix, std::move(opener)});
}

Expected<std::unique_ptr<FrameSource>> FrameSource::open(const std::string& input) {
  if (input.empty()) return Error{"input not found: (empty path)", input, 0, 0, {}};
  {
    Opener opener;
    {
      std::scoped_lock lock(schemes_mutex());
      for (const Scheme& s : schemes())
        if (input.starts_with(s.prefix)) opener = s.opener;
    }
    if (opener) return opener(input);
  }
  if (is_live_input(input)) return open_live(input);
  std::error_code ec;
  const fs::file_status st = fs::status(input, ec);
  if (fs::is_directory(st)) return open_directory(input);
  if (fs::is_regular_file(st)) {
    if (is_image_file(input)) {
      return std::unique_ptr<FrameSource>(std::make_unique<FileListSource>(std::vector<std::string>{input}));
    }
  }
  if (fs::exists(st)) {  // a video file, or a device such as /dev/video0
    for (const cv::VideoCaptureAPIs api : video_backends()) {
      try {
        auto cap = std::make_unique<cv::VideoCapture>(input, api);
        if (cap->isOpened()) return std::unique_ptr<FrameSource>(std::make_unique<VideoSource>(std::move(cap), input));
      } catch (const cv::Exception&) {
        // Try the next back-end; reported below when none opens it.
      }
    }
    return Error{fmt::format("cannot open video {}", input), input, 0, 0, {}};
  }
  if (const std::optional<Pattern> pattern = Pattern::parse(input)) return open_pattern(input, *pattern);
  return Error{fmt::format("input not found: {}", input), input, 0, 0, {}};
}

}  // namespace v4r::io
