// v4r - robust model-based object tracking. MIT licence.
// The monitoring page of `v4r serve --http` in a real browser: Debian's Chromium, headless, loads
// http://127.0.0.1:PORT/, runs the page's script and shows the live overlay stream. The test checks
// the rendered page (a screenshot) against the JPEG the server streams and the status table (the
// DOM after the script ran) against the server's own counters.
//
// Without Chromium the test is skipped, unless V4R_REQUIRE_CHROMIUM is set (`make test` installs
// Chromium and sets it, so CI always runs it).
#include <cstdlib>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "fixture.hpp"

namespace v4r::server::test {
namespace {

/// The Chromium binary: $V4R_CHROMIUM, else the first of the usual names on PATH; "" if none.
std::string find_chromium() {
  if (const char* env = std::getenv("V4R_CHROMIUM"); env != nullptr && *env != '\0') return env;
  for (const char* name : {"chromium", "chromium-browser", "google-chrome"}) {
    if (std::system(("command -v " + std::string(name) + " > /dev/null 2>&1").c_str()) == 0) return name;
  }
  return {};
}

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Runs headless Chromium on `url` with `what` (--screenshot=F or --dump-dom), 1.5 s of page time
/// for the script to poll the status; returns the exit code.
int run_chromium(const std::string& chromium, const fs::path& work, const std::string& url, const std::string& what,
                 const fs::path& out) {
  const std::string cmd = "timeout 120 " + chromium +
                          " --headless --no-sandbox --disable-gpu --disable-dev-shm-usage --no-first-run"
                          " --disable-background-networking --disable-extensions --disable-sync"
                          " --force-device-scale-factor=1 --hide-scrollbars --window-size=800,1100"
                          " --timeout=1500 --user-data-dir=" +
                          (work / "chromium-profile").string() + " " + what + " '" + url + "' > " + out.string() +
                          " 2> " + (work / "chromium-stderr.txt").string();
  return std::system(cmd.c_str());
}

/// The first JPEG of an MJPEG response (head included), decoded; empty on failure.
cv::Mat first_jpeg(const std::string& stream) {
  const auto part = stream.find("--v4rframe\r\nContent-Type: image/jpeg\r\nContent-Length: ");
  if (part == std::string::npos) return {};
  const auto len_at = stream.find("Content-Length: ", part) + 16;
  const std::size_t len = std::stoul(stream.substr(len_at, 12));
  const auto body = stream.find("\r\n\r\n", part) + 4;
  if (body + len > stream.size()) return {};
  const std::vector<unsigned char> bytes(stream.begin() + static_cast<std::ptrdiff_t>(body),
                                         stream.begin() + static_cast<std::ptrdiff_t>(body + len));
  return cv::imdecode(bytes, cv::IMREAD_COLOR);
}

/// Text of the table cell that follows <th>key</th>, or "" when absent.
std::string cell(const std::string& dom, const std::string& key) {
  const std::regex re("<th>" + key + "</th><td>([^<]*)</td>");
  std::smatch m;
  return std::regex_search(dom, m, re) ? m[1].str() : std::string();
}

/// Pixels of the overlay's "found" colour (pure green lines, after JPEG) inside `roi`.
int green_pixels(const cv::Mat& bgr) {
  int n = 0;
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x) {
      const cv::Vec3b p = bgr.at<cv::Vec3b>(y, x);
      if (p[1] > 170 && p[0] < 110 && p[2] < 110) ++n;
    }
  return n;
}

TEST(MonitorPage, HeadlessChromiumShowsTheLiveOverlayAndTheStatus) {
  const std::string chromium = find_chromium();
  if (chromium.empty()) {
    if (std::getenv("V4R_REQUIRE_CHROMIUM") != nullptr) FAIL() << "V4R_REQUIRE_CHROMIUM is set but Chromium is not found";
    GTEST_SKIP() << "Chromium not installed (Debian package chromium; `make test` installs it)";
  }
  const Sequence& seq = ship_sequence();
  ServerOptions o = test_options(seq, 30.0);
  o.http_port = 0;
  o.token = "page-token";  // the page must carry ?token= into its stream and status requests
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  ASSERT_TRUE(is_ok(ask(c, "Auth token=page-token")));
  add_model_inline(c, "ship", seq.cao);
  ASSERT_TRUE(is_ok(ask(c, set_pose("ship", seq.truth[0]))));
  ASSERT_EQ(ask(c, "Display on"), "OK Display on");
  ASSERT_TRUE(is_ok(ask(c, "Start")));
  // Play the whole sequence: afterwards the stream's newest image (the last overlay) is stable.
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while (!srv->stats().end_of_input && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(20ms);
  ASSERT_TRUE(srv->stats().end_of_input);
  ASSERT_EQ(srv->stats().frames, seq.count);

  const std::uint16_t port = srv->http_port();
  const cv::Mat streamed = first_jpeg(http_get(port, "/stream.mjpg?token=page-token", 100000));
  ASSERT_FALSE(streamed.empty()) << "no JPEG in the MJPEG stream";
  ASSERT_EQ(streamed.cols, seq.camera.width);
  ASSERT_EQ(streamed.rows, seq.camera.height);
  const int green_streamed = green_pixels(streamed);
  EXPECT_GT(green_streamed, 300) << "the streamed image shows no tracked (green) edges";

  const std::string url = "http://127.0.0.1:" + std::to_string(port) + "/?token=page-token";
  const fs::path shot = seq.dir / "monitor.png", dom_file = seq.dir / "monitor.html";
  ASSERT_EQ(run_chromium(chromium, seq.dir, url, "--screenshot=" + shot.string(), seq.dir / "chromium-stdout.txt"), 0)
      << read_file(seq.dir / "chromium-stderr.txt");
  ASSERT_EQ(run_chromium(chromium, seq.dir, url, "--dump-dom", dom_file), 0) << read_file(seq.dir / "chromium-stderr.txt");

  // The screenshot holds the streamed image at 1:1, found by normalised cross-correlation.
  const cv::Mat page = cv::imread(shot.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(page.empty()) << "Chromium wrote no screenshot";
  ASSERT_GE(page.cols, streamed.cols);
  ASSERT_GE(page.rows, streamed.rows);
  cv::Mat score;
  cv::matchTemplate(page, streamed, score, cv::TM_CCOEFF_NORMED);
  double best = 0.0;
  cv::Point at;
  cv::minMaxLoc(score, nullptr, &best, nullptr, &at);
  std::printf("[monitor] image found in the page at (%d, %d), correlation %.4f; green pixels %d streamed\n", at.x, at.y,
              best, green_streamed);
  if (best <= 0.97) {  // keep the evidence: the sequence folder is removed at exit
    const fs::path keep = fs::temp_directory_path() / "v4r_monitor_page_failure.png";
    std::error_code ec;
    fs::copy_file(shot, keep, fs::copy_options::overwrite_existing, ec);
    ADD_FAILURE() << "the page does not show the streamed overlay (correlation " << best << "); screenshot kept in "
                  << keep.string();
  }
  const cv::Mat shown = page(cv::Rect(at, streamed.size()));
  EXPECT_GT(green_pixels(shown), green_streamed / 2) << "the overlay's edges are not visible on the page";

  // The status table, filled by the page's script from /status.json.
  const std::string dom = read_file(dom_file);
  EXPECT_EQ(cell(dom, "frame"), std::to_string(seq.count - 1)) << dom;
  EXPECT_EQ(cell(dom, "end_of_input"), "true");
  EXPECT_EQ(cell(dom, "display"), "true");
  EXPECT_EQ(cell(dom, "overruns"), "0");
  EXPECT_GT(std::stoi("0" + cell(dom, "features_found")), 5);
  EXPECT_EQ(cell(dom, "ship"), "tracking");
  EXPECT_NE(dom.find("src=\"/stream.mjpg?token=page-token\""), std::string::npos);

  // Without the token the page's requests are refused.
  ASSERT_EQ(run_chromium(chromium, seq.dir, "http://127.0.0.1:" + std::to_string(port) + "/", "--dump-dom", dom_file), 0);
  EXPECT_EQ(read_file(dom_file).find("<th>frame</th>"), std::string::npos);
}

}  // namespace
}  // namespace v4r::server::test
