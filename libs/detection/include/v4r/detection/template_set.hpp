// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "v4r/core/expected.hpp"
#include "v4r/detection/detector_params.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::detection {

/// \brief One feature of a template: a quantised edge orientation at an offset (pixels of the
/// template's level) from the template's anchor, the projection of the model's centre.
struct Feature {
  std::int16_t x = 0, y = 0;
  std::uint8_t orientation = 0;
};

/// \brief A template: its features (a range of TemplateLevel::features) and their bounding box.
struct Template {
  std::uint32_t first = 0, count = 0;
  std::int16_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;  ///< feature offsets span [x0, x1] x [y0, y1]
};

/// \brief The templates of one image level (1/2 or 1/4 resolution).
struct TemplateLevel {
  double scale = 0.5;  ///< level pixels per full-resolution pixel
  std::vector<Template> templates;
  std::vector<Feature> features;
};

/// \brief A sampled view: the pose T_cam_obj of the model with its centre on the optical axis,
/// and its grid indices (elevation, azimuth, in-plane rotation, distance).
struct TemplateView {
  geometry::SE3 T_cam_obj;
  std::int16_t elevation = 0, azimuth = 0, inplane = 0, distance = 0;
};

/// \brief LINE-2D-style templates of a model over a view range, organised coarse to fine: every
/// view has a fine template (1/2 resolution); every second view along each grid axis also has a
/// coarse one (1/4 resolution) whose children are the fine views within one grid step of it.
/// Offsets are in pixels of a camera with the focal lengths `fx`, `fy` (no distortion).
struct TemplateSet {
  static constexpr std::uint32_t kFormatVersion = 1;

  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< object frame: centre of the bounding box
  double fx = 0.0, fy = 0.0;                         ///< pixels
  int n_elevation = 0, n_azimuth = 0, n_inplane = 0, n_distance = 0;
  bool azimuth_wraps = false;  ///< the azimuth grid closes the full circle
  std::vector<TemplateView> views;  ///< index = ((distance * n_elevation + elevation) * n_azimuth + azimuth) * n_inplane + inplane
  TemplateLevel fine;               ///< one template per view
  TemplateLevel coarse;             ///< one template per entry of coarse_views
  std::vector<std::uint32_t> coarse_views;   ///< view of each coarse template
  std::vector<std::uint32_t> child_offsets;  ///< children of coarse k: children[child_offsets[k] .. child_offsets[k+1])
  std::vector<std::uint32_t> children;       ///< view indices

  [[nodiscard]] std::size_t view_index(int distance, int elevation, int azimuth, int inplane) const {
    return ((static_cast<std::size_t>(distance) * n_elevation + elevation) * n_azimuth + azimuth) * n_inplane + inplane;
  }
};

/// \brief Centre of a model's bounding box (object frame, metres; cylinders and arcs by their
/// boxes) and the radius of the sphere about it that holds every junction and arc.
struct ModelExtent {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0.0;
};
ModelExtent model_extent(const model::Model& model);

/// Called during building with (views done, views in all).
using BuildProgress = std::function<void(std::size_t, std::size_t)>;

/// Builds the templates of `model` seen by a camera with focal lengths `cam.fx`, `cam.fy` over
/// `p.views` with the sampling of `p.templates`. Errors: invalid parameters (named field), a
/// model without edges, a view range that gives no template.
Expected<TemplateSet> build_templates(const model::Model& model, const geometry::PinholeCamera& cam,
                                      const DetectorParams& p, const BuildProgress& progress = {});

/// The pose of a template view moved so that the model's centre projects onto pixel
/// (`u`, `v`) of `cam` (full resolution): the view turned about the camera centre, which keeps
/// the model's appearance up to perspective.
geometry::SE3 pose_at_pixel(const TemplateSet& set, std::uint32_t view, const geometry::PinholeCamera& cam, double u,
                            double v);

}  // namespace v4r::detection
