// v4r - robust model-based object tracking. MIT licence.
//
// Pose files (six numbers) and pose CSVs (frame,tx,ty,tz,qw,qx,qy,qz). Numbers are written with
// 17 significant digits, so a double survives save -> load unchanged.

#include "v4r/io/pose_io.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <array>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string_view>
#include <system_error>
#include <utility>

namespace v4r::io {
namespace {

/// Largest accepted deviation of a CSV quaternion's norm from 1 (written ones are within 1e-15).
constexpr double kQuaternionNormTolerance = 1e-3;

enum class NumberStatus { kOk, kNotNumber, kNotFinite };

/// Parses all of `s` as a double, locale-independently (a leading '+' is accepted).
NumberStatus parse_number(std::string_view s, double& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return NumberStatus::kNotNumber;
  const char* end = s.data() + s.size();
  const auto [ptr, ec] = std::from_chars(s.data(), end, out);
  if (ec == std::errc::result_out_of_range) return NumberStatus::kNotFinite;
  if (ec != std::errc() || ptr != end) return NumberStatus::kNotNumber;
  return std::isfinite(out) ? NumberStatus::kOk : NumberStatus::kNotFinite;
}

/// A double written with enough digits to be read back exactly.
std::string exact(double v) { return fmt::format("{:.17g}", v); }

/// Reads a whole file; errors name the path.
Expected<std::string> read_text(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Error{fmt::format("file not found: {}", path), path, 0, 0, {}};
  if (std::filesystem::is_directory(path, ec)) {
    return Error{fmt::format("is a directory, not a file: {}", path), path, 0, 0, {}};
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{fmt::format("cannot open {}", path), path, 0, 0, {}};
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return Error{fmt::format("cannot read {}", path), path, 0, 0, {}};
  return ss.str();
}

Expected<void> write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) return Error{fmt::format("cannot open {} for writing", path), path, 0, 0, {}};
  f << text;
  f.close();
  if (!f) return Error{fmt::format("cannot write {}", path), path, 0, 0, {}};
  return {};
}

/// Splits text into lines (LF, CRLF or CR), without the terminators.
std::vector<std::string_view> split_lines(std::string_view text) {
  std::vector<std::string_view> lines;
  std::size_t start = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '\n' || text[i] == '\r') {
      lines.push_back(text.substr(start, i - start));
      if (text[i] == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
      start = i + 1;
    }
  }
  if (start < text.size()) lines.push_back(text.substr(start));
  return lines;
}

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\f' || c == '\v'; }

/// One CSV field: its text (trimmed, outer double quotes removed) and its 1-based column.
struct Field {
  std::string_view text;
  int column = 0;
};

std::vector<Field> split_csv(std::string_view line) {
  std::vector<Field> fields;
  std::size_t start = 0;
  while (true) {
    std::size_t end = line.find(',', start);
    if (end == std::string_view::npos) end = line.size();
    std::size_t a = start, b = end;
    while (a < b && is_blank(line[a])) ++a;
    while (b > a && is_blank(line[b - 1])) --b;
    if (b - a >= 2 && line[a] == '"' && line[b - 1] == '"') {
      ++a;
      --b;
    }
    fields.push_back(Field{line.substr(a, b - a), static_cast<int>(a) + 1});
    if (end == line.size()) break;
    start = end + 1;
  }
  return fields;
}

/// True for an empty line or a '#' comment line.
bool skippable(std::string_view line) {
  std::size_t i = 0;
  while (i < line.size() && is_blank(line[i])) ++i;
  return i == line.size() || line[i] == '#';
}

}  // namespace

Eigen::Quaterniond canonical(const Eigen::Quaterniond& q) {
  if (q.w() > 0.0 || (q.w() == 0.0 && (q.x() > 0.0 || (q.x() == 0.0 && (q.y() > 0.0 || (q.y() == 0.0 && q.z() >= 0.0))))))
    return q;
  return Eigen::Quaterniond(-q.w(), -q.x(), -q.y(), -q.z());
}

Expected<PoseNumbers> parse_pose_numbers(const std::string& text, const std::string& source) {
  constexpr std::array<const char*, 6> kNames{"tx", "ty", "tz", "rx", "ry", "rz"};
  std::array<double, 6> v{};
  std::size_t count = 0;
  int last_line = 1, last_end_column = 1;  // just after the last number (for "too few")
  const std::vector<std::string_view> lines = split_lines(text);
  for (std::size_t li = 0; li < lines.size(); ++li) {
    std::string_view line = lines[li];
    const std::size_t hash = line.find('#');
    if (hash != std::string_view::npos) line = line.substr(0, hash);
    const int line_no = static_cast<int>(li) + 1;
    std::size_t i = 0;
    while (i < line.size()) {
      if (is_blank(line[i]) || line[i] == ',') {
        ++i;
        continue;
      }
      std::size_t j = i;
      while (j < line.size() && !is_blank(line[j]) && line[j] != ',') ++j;
      const std::string_view token = line.substr(i, j - i);
      const int column = static_cast<int>(i) + 1;
      if (count == v.size()) {
        return Error{fmt::format("expected exactly six numbers (tx ty tz rx ry rz), found a seventh: '{}'", token),
                     source,
                     line_no,
                     column,
                     {}};
      }
      double x = 0.0;
      switch (parse_number(token, x)) {
        case NumberStatus::kOk:
          break;
        case NumberStatus::kNotFinite:
          return Error{fmt::format("not a finite number: '{}'", token), source, line_no, column, kNames[count]};
        case NumberStatus::kNotNumber:
          return Error{fmt::format("expected a number, got '{}'", token), source, line_no, column, kNames[count]};
      }
      v[count++] = x;
      last_line = line_no;
      last_end_column = static_cast<int>(j) + 1;
      i = j;
    }
  }
  if (count < v.size()) {
    return Error{fmt::format("expected six numbers (tx ty tz rx ry rz), got {}; {} is missing", count, kNames[count]),
                 source, last_line, last_end_column, kNames[count]};
  }
  return v;
}

geometry::SE3 pose_from_numbers(const PoseNumbers& v) {
  return geometry::SE3::from_rvec(Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5]));
}

Expected<geometry::SE3> parse_pose(const std::string& text, const std::string& source) {
  Expected<PoseNumbers> v = parse_pose_numbers(text, source);
  if (!v) return v.error();
  return pose_from_numbers(*v);
}

Expected<PoseNumbers> load_pose_numbers(const std::string& path) {
  Expected<std::string> text = read_text(path);
  if (!text) return text.error();
  return parse_pose_numbers(*text, path);
}

Expected<geometry::SE3> load_pose_file(const std::string& path) {
  Expected<PoseNumbers> v = load_pose_numbers(path);
  if (!v) return v.error();
  return pose_from_numbers(*v);
}

Expected<void> save_pose_file(const std::string& path, const geometry::SE3& T) {
  const Eigen::Vector3d t = T.translation();
  const Eigen::Vector3d r = T.rvec();
  if (!t.allFinite() || !r.allFinite()) return Error{"pose is not finite", path, 0, 0, {}};
  std::string out = "# T_cam_obj: tx ty tz (metres) rx ry rz (rotation vector, radians)\n";
  out += fmt::format("{} {} {} {} {} {}\n", exact(t.x()), exact(t.y()), exact(t.z()), exact(r.x()), exact(r.y()),
                     exact(r.z()));
  return write_text(path, out);
}

Expected<std::vector<PoseRow>> load_pose_csv(const std::string& path) {
  Expected<std::string> text = read_text(path);
  if (!text) return text.error();
  const std::vector<std::string_view> lines = split_lines(*text);

  constexpr std::array<const char*, 8> kColumns{"frame", "tx", "ty", "tz", "qw", "qx", "qy", "qz"};
  std::array<int, 8> index{};
  index.fill(-1);
  std::size_t li = 0;
  while (li < lines.size() && skippable(lines[li])) ++li;
  if (li == lines.size()) {
    return Error{fmt::format("missing header line ({})", fmt::join(kColumns, ",")), path, 1, 1, {}};
  }
  const int header_line = static_cast<int>(li) + 1;
  const std::vector<Field> header = split_csv(lines[li]);
  for (std::size_t c = 0; c < header.size(); ++c) {
    for (std::size_t k = 0; k < kColumns.size(); ++k) {
      if (header[c].text != kColumns[k]) continue;
      if (index[k] >= 0) {
        return Error{fmt::format("column '{}' appears twice in the header", kColumns[k]), path, header_line,
                     header[c].column, kColumns[k]};
      }
      index[k] = static_cast<int>(c);
    }
  }
  for (std::size_t k = 0; k < kColumns.size(); ++k) {
    if (index[k] < 0) {
      return Error{fmt::format("header has no column '{}' (needs {})", kColumns[k], fmt::join(kColumns, ",")), path,
                   header_line, 0, kColumns[k]};
    }
  }

  std::vector<PoseRow> rows;
  for (++li; li < lines.size(); ++li) {
    if (skippable(lines[li])) continue;
    const int line_no = static_cast<int>(li) + 1;
    const std::vector<Field> fields = split_csv(lines[li]);
    std::array<double, 8> v{};
    for (std::size_t k = 0; k < kColumns.size(); ++k) {
      const auto c = static_cast<std::size_t>(index[k]);
      if (c >= fields.size()) {
        return Error{fmt::format("row has {} fields, column '{}' is number {}", fields.size(), kColumns[k], c + 1),
                     path, line_no, static_cast<int>(lines[li].size()) + 1, kColumns[k]};
      }
      const Field& f = fields[c];
      switch (parse_number(f.text, v[k])) {
        case NumberStatus::kOk:
          break;
        case NumberStatus::kNotFinite:
          return Error{fmt::format("not a finite number: '{}'", f.text), path, line_no, f.column, kColumns[k]};
        case NumberStatus::kNotNumber:
          return Error{fmt::format("expected a number, got '{}'", f.text), path, line_no, f.column, kColumns[k]};
      }
    }
    const Field& frame_field = fields[static_cast<std::size_t>(index[0])];
    if (v[0] != std::floor(v[0]) || std::abs(v[0]) > 2e9) {
      return Error{fmt::format("frame must be an integer, got '{}'", frame_field.text), path, line_no,
                   frame_field.column, "frame"};
    }
    const Eigen::Quaterniond q(v[4], v[5], v[6], v[7]);
    const double norm = q.norm();
    if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
      const Field& qw = fields[static_cast<std::size_t>(index[4])];
      return Error{fmt::format("quaternion (qw,qx,qy,qz) is not unit: norm {}", norm), path, line_no, qw.column, "qw"};
    }
    PoseRow row;
    row.frame = static_cast<int>(v[0]);
    row.T_cam_obj = geometry::SE3(q, Eigen::Vector3d(v[1], v[2], v[3]));
    rows.push_back(row);
  }
  return rows;
}

Expected<void> save_pose_csv(const std::string& path, const std::vector<PoseRow>& rows) {
  std::string out = "frame,tx,ty,tz,qw,qx,qy,qz\n";
  for (const PoseRow& r : rows) {
    const Eigen::Vector3d& t = r.T_cam_obj.translation();
    const Eigen::Quaterniond q = canonical(r.T_cam_obj.quaternion());
    if (!t.allFinite() || !q.coeffs().allFinite()) {
      return Error{fmt::format("pose of frame {} is not finite", r.frame), path, 0, 0, {}};
    }
    out += fmt::format("{},{},{},{},{},{},{},{}\n", r.frame, exact(t.x()), exact(t.y()), exact(t.z()), exact(q.w()),
                       exact(q.x()), exact(q.y()), exact(q.z()));
  }
  return write_text(path, out);
}

}  // namespace v4r::io
