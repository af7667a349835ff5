// v4r - robust model-based object tracking. MIT licence.
#pragma once

// \brief The one logging facade of v4r. Library code logs through these macros (spdlog), never
// through std::cout / std::cerr. Nothing is logged on the real-time path.
#include <spdlog/spdlog.h>

#define V4R_LOG_INFO(...) ::spdlog::info(__VA_ARGS__)
#define V4R_LOG_WARN(...) ::spdlog::warn(__VA_ARGS__)
#define V4R_LOG_ERROR(...) ::spdlog::error(__VA_ARGS__)
#define V4R_LOG_DEBUG(...) ::spdlog::debug(__VA_ARGS__)
