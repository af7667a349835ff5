// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/http_request.hpp"

#include <algorithm>

#include <fmt/format.h>

namespace v4r::server {

namespace {

Unexpected bad(std::string msg) { return Unexpected{Error{std::move(msg), "<http>", 0, 0, {}}}; }

/// RFC 9110 token characters.
bool is_tchar(char c) {
  if ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9')) return true;
  return std::string_view("!#$%&'*+-.^_`|~").find(c) != std::string_view::npos;
}

bool visible(char c) { return c > 0x20 && c < 0x7F; }

}  // namespace

Expected<HttpRequest> parse_http_request(std::string_view head) {
  if (head.size() > kMaxHttpHeadBytes) head = head.substr(0, kMaxHttpHeadBytes + 1);
  HttpRequest r;
  std::size_t pos = 0;
  int line_no = 0;
  for (;;) {
    const std::size_t nl = head.find('\n', pos);
    if (nl == std::string_view::npos) {
      if (head.size() > kMaxHttpHeadBytes) return bad(fmt::format("request head over {} bytes", kMaxHttpHeadBytes));
      return bad("request head not ended by an empty line");
    }
    if (nl >= kMaxHttpHeadBytes) return bad(fmt::format("request head over {} bytes", kMaxHttpHeadBytes));
    std::string_view line = head.substr(pos, nl - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos = nl + 1;
    ++line_no;
    for (std::size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (c != '\t' && (c < 0x20 || c > 0x7E))
        return bad(fmt::format("line {}, column {}: byte 0x{:02x} not allowed", line_no, i + 1,
                               static_cast<unsigned>(static_cast<unsigned char>(c))));
    }
    if (line_no == 1) {
      const std::size_t s1 = line.find(' ');
      const std::size_t s2 = s1 == std::string_view::npos ? s1 : line.find(' ', s1 + 1);
      if (s2 == std::string_view::npos || line.find(' ', s2 + 1) != std::string_view::npos)
        return bad("request line is not 'METHOD TARGET HTTP/1.x'");
      const std::string_view method = line.substr(0, s1), target = line.substr(s1 + 1, s2 - s1 - 1),
                             version = line.substr(s2 + 1);
      if (method.empty() || !std::all_of(method.begin(), method.end(), is_tchar)) return bad("method is not a token");
      if (target.empty() || target.front() != '/' || !std::all_of(target.begin(), target.end(), visible))
        return bad("target does not start with '/'");
      if (version != "HTTP/1.0" && version != "HTTP/1.1") return bad("not HTTP/1.0 or HTTP/1.1");
      r.method = method;
      r.version = version;
      const std::size_t q = target.find('?');
      r.path = target.substr(0, q);
      if (q != std::string_view::npos) r.query = target.substr(q + 1);
      continue;
    }
    if (line.empty()) return r;  // end of the head
    const std::size_t colon = line.find(':');
    if (colon == 0 || colon == std::string_view::npos ||
        !std::all_of(line.begin(), line.begin() + static_cast<std::ptrdiff_t>(colon), is_tchar))
      return bad(fmt::format("line {}: not a header 'Name: value'", line_no));
  }
}

bool query_has_token(std::string_view query, std::string_view token) {
  if (token.empty()) return true;
  // token=<value> among the &-separated parameters (no percent-decoding: tokens are expected to
  // be URL-safe), compared in time independent of the content.
  bool found = false;
  std::size_t i = 0;
  while (i <= query.size()) {
    std::size_t j = query.find('&', i);
    if (j == std::string_view::npos) j = query.size();
    const std::string_view kv = query.substr(i, j - i);
    if (kv.starts_with("token=")) {
      const std::string_view v = kv.substr(6);
      unsigned char diff = v.size() == token.size() ? 0 : 1;
      for (std::size_t k = 0; k < std::max(v.size(), token.size()); ++k)
        diff |= static_cast<unsigned char>((k < v.size() ? v[k] : 0) ^ (k < token.size() ? token[k] : 0));
      found = found || diff == 0;
    }
    i = j + 1;
  }
  return found;
}

}  // namespace v4r::server
