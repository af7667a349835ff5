// v4r - robust model-based object tracking. MIT licence.
// One degree in radians, for the detection tests.
#pragma once

inline constexpr double kDeg = 3.14159265358979323846 / 180.0;
