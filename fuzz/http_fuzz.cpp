// v4r - robust model-based object tracking. MIT licence.
// libFuzzer target for the request parser of the HTTP monitor (`v4r serve --http`): any bytes a
// browser or an attacker sends must give a request or an error, never a crash, a hang or a
// sanitizer report. Besides that it checks what the monitor relies on, and aborts when one fails:
//   - an accepted request has a token method, a path starting with '/' without '?', an HTTP/1.x
//     version, printable bytes only, and the head it came from ends with an empty line within
//     kMaxHttpHeadBytes;
//   - the request line rebuilt from the parts parses back to the same parts;
//   - the token check accepts a query only when it carries exactly `token=<token>` as one of its
//     &-separated parameters.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "v4r/server/http_request.hpp"

namespace vs = v4r::server;

namespace {

void check(bool ok, const char* what, std::string_view input) {
  if (ok) return;
  std::fprintf(stderr, "property violated: %s\ninput (%zu bytes): %.*s\n", what, input.size(),
               static_cast<int>(input.size() > 300 ? 300 : input.size()), input.data());
  std::abort();
}

bool printable(std::string_view s) {
  for (char c : s)
    if (c < 0x20 || c > 0x7E) return false;
  return true;
}

/// The reference meaning of "the query carries token=<t>".
bool has_param(std::string_view query, std::string_view t) {
  const std::string want = "token=" + std::string(t);
  std::size_t i = 0;
  while (i <= query.size()) {
    std::size_t j = query.find('&', i);
    if (j == std::string_view::npos) j = query.size();
    if (query.substr(i, j - i) == want) return true;
    i = j + 1;
  }
  return false;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view in(reinterpret_cast<const char*>(data), size);
  const auto r = vs::parse_http_request(in);
  if (r) {
    check(!r->method.empty() && printable(r->method), "method", in);
    check(!r->path.empty() && r->path.front() == '/' && r->path.find('?') == std::string::npos, "path", in);
    check(printable(r->path) && printable(r->query), "printable target", in);
    check(r->version == "HTTP/1.0" || r->version == "HTTP/1.1", "version", in);
    const std::size_t end = in.find("\n\n") < in.find("\n\r\n") ? in.find("\n\n") : in.find("\n\r\n");
    check(end != std::string_view::npos && end < vs::kMaxHttpHeadBytes, "head ends within the limit", in);
    const std::string line =
        r->method + " " + r->path + (r->query.empty() ? "" : "?") + r->query + " " + r->version + "\r\n\r\n";
    const auto back = vs::parse_http_request(line);
    check(back && back->method == r->method && back->path == r->path && back->query == r->query &&
              back->version == r->version,
          "request line round trip", in);
  } else {
    check(!r.error().message.empty(), "error without a message", in);
  }
  // The token check on arbitrary queries: the first bytes are the token, the rest the query.
  const std::size_t split = size > 0 ? data[0] % 16 : 0;
  if (size > split + 1) {
    const std::string_view token = in.substr(1, split), query = in.substr(1 + split);
    check(vs::query_has_token(query, token) == (token.empty() || has_param(query, token)), "token check", in);
  }
  return 0;
}
