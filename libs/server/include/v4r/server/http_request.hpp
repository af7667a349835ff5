// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include "v4r/core/expected.hpp"

namespace v4r::server {

/// \brief The request line of an HTTP/1.x request to the monitoring page.
struct HttpRequest {
  std::string method;   ///< e.g. "GET"
  std::string path;     ///< target without the query, starts with '/'
  std::string query;    ///< after '?', without it ("" when none)
  std::string version;  ///< "HTTP/1.0" or "HTTP/1.1"
};

/// Longest request head the monitor reads (request line and header lines), bytes.
inline constexpr std::size_t kMaxHttpHeadBytes = 8192;

/// Parses an HTTP request head: the request line `METHOD SP TARGET SP HTTP/1.x` and header lines
/// `Name: value`, each ended by CRLF (a bare LF is accepted), up to the first empty line (bytes
/// after it are ignored). Rejects, with a message: a head over kMaxHttpHeadBytes or without its
/// empty line, control bytes and bytes above 0x7E, a method that is not a token, a target that does
/// not start with '/', another protocol or version, a header line without a name and ':'.
/// Never throws for any input (fuzzed: fuzz/http_fuzz.cpp).
Expected<HttpRequest> parse_http_request(std::string_view head);

/// True when the &-separated query carries `token=<token>` exactly (compared in time independent
/// of the content); always true for an empty token.
bool query_has_token(std::string_view query, std::string_view token);

}  // namespace v4r::server
