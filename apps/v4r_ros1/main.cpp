// v4r - robust model-based object tracking. MIT licence.
//
// `v4r_ros1`: the tracker as a ROS 1 node, after visp_tracker's conventions.
//   private parameters  ~model (path, required), ~init_pose ("tx ty tz rx ry rz", optional),
//                       ~config (YAML of `v4r config`, optional), ~object (name, default "object"),
//                       ~model_scale (model units -> metres, default 1), ~queue_size (images, default 1:
//                       the newest image first)
//   subscribes          image (sensor_msgs/Image: mono8, bgr8, rgb8), camera_info (sensor_msgs/CameraInfo),
//                       object_position_hint (geometry_msgs/PoseStamped: re-initialises the tracker)
//   publishes           object_position_covariance (geometry_msgs/PoseWithCovarianceStamped),
//                       object_position (geometry_msgs/TransformStamped), status (std_msgs/String),
//                       and the same transform on /tf (image frame -> ~object); status is the track
//                       status per image (tracking, degraded, lost), "waiting: ..." before camera_info
//                       and a pose, "error: ..." for an unsupported image, "reinitialised ..." on a hint
// Every output carries the image's stamp and frame_id. This file is C++17 (ROS 1 headers do not
// compile as C++20): it sees v4r only through the facade v4r/embed/object_tracker.hpp.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>
#include <tf2_ros/transform_broadcaster.h>

#include "v4r/embed/object_tracker.hpp"

namespace {

using Clock = std::chrono::steady_clock;

/// \brief Image-received-to-pose-published latencies (ms), kept in a buffer sized once.
class LatencyLog {
 public:
  explicit LatencyLog(std::size_t capacity) { ms_.reserve(capacity); }
  void add(double ms) {
    if (ms_.size() < ms_.capacity()) ms_.push_back(ms);
  }
  /// "n=N p50=X ms p99=Y ms max=Z ms", or "no frames".
  std::string summary() {
    if (ms_.empty()) return "no frames";
    std::vector<double> s = ms_;
    std::sort(s.begin(), s.end());
    const auto at = [&](double p) { return s[std::min(s.size() - 1, static_cast<std::size_t>(p * (s.size() - 1) + 0.5))]; };
    char buf[160];
    std::snprintf(buf, sizeof buf, "n=%zu p50=%.3f ms p99=%.3f ms max=%.3f ms", s.size(), at(0.5), at(0.99), s.back());
    return buf;
  }

 private:
  std::vector<double> ms_;
};

class TrackerNode {
 public:
  TrackerNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, std::unique_ptr<v4r::embed::ObjectTracker> tracker,
              std::string object, int queue_size)
      : tracker_(std::move(tracker)), object_(std::move(object)), latency_(1 << 20) {
    pose_pub_ = nh.advertise<geometry_msgs::PoseWithCovarianceStamped>("object_position_covariance", 10);
    transform_pub_ = nh.advertise<geometry_msgs::TransformStamped>("object_position", 10);
    status_pub_ = nh.advertise<std_msgs::String>("status", 10);
    info_sub_ = nh.subscribe("camera_info", 1, &TrackerNode::on_camera_info, this);
    image_sub_ = nh.subscribe("image", static_cast<std::uint32_t>(queue_size), &TrackerNode::on_image, this,
                              ros::TransportHints().tcpNoDelay());
    hint_sub_ = nh.subscribe("object_position_hint", 1, &TrackerNode::on_hint, this);
    (void)pnh;
  }
  ~TrackerNode() { std::printf("v4r_ros1: latency image received -> pose published: %s\n", latency_.summary().c_str()); }

 private:
  void on_camera_info(const sensor_msgs::CameraInfoConstPtr& info) {
    v4r::embed::CameraIntrinsics c;
    c.width = static_cast<int>(info->width);
    c.height = static_cast<int>(info->height);
    c.fx = info->K[0];
    c.fy = info->K[4];
    c.cx = info->K[2];
    c.cy = info->K[5];
    if (!info->D.empty()) {
      if (info->distortion_model != "plumb_bob" && info->distortion_model != "rational_polynomial") {
        ROS_ERROR_THROTTLE(5.0, "v4r_ros1: camera_info: distortion model '%s' is not supported (plumb_bob)",
                           info->distortion_model.c_str());
        return;
      }
      for (std::size_t i = 0; i < 5 && i < info->D.size(); ++i) c.dist[i] = info->D[i];
    }
    std::string error;
    if (!tracker_->set_camera(c, error)) ROS_ERROR_THROTTLE(5.0, "v4r_ros1: camera_info: %s", error.c_str());
  }

  void on_hint(const geometry_msgs::PoseStampedConstPtr& hint) {
    const auto& p = hint->pose;
    v4r::embed::Pose pose;
    pose.t = {p.position.x, p.position.y, p.position.z};
    pose.q = {p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z};
    const double n = pose.q[0] * pose.q[0] + pose.q[1] * pose.q[1] + pose.q[2] * pose.q[2] + pose.q[3] * pose.q[3];
    if (!(n > 0.5 && n < 1.5) || !(pose.t[2] > 0.0)) {
      ROS_ERROR("v4r_ros1: object_position_hint ignored: needs a unit quaternion and z > 0 (camera frame)");
      return;
    }
    tracker_->set_pose(pose);
    publish_status(hint->header, "reinitialised from object_position_hint");
    ROS_INFO("v4r_ros1: re-initialised from object_position_hint (%.3f %.3f %.3f)", pose.t[0], pose.t[1], pose.t[2]);
  }

  void on_image(const sensor_msgs::ImageConstPtr& img) {
    const Clock::time_point received = Clock::now();
    v4r::embed::PixelFormat format;
    if (img->encoding == "mono8") {
      format = v4r::embed::PixelFormat::kMono8;
    } else if (img->encoding == "bgr8") {
      format = v4r::embed::PixelFormat::kBgr8;
    } else if (img->encoding == "rgb8") {
      format = v4r::embed::PixelFormat::kRgb8;
    } else {
      publish_status(img->header, "error: image encoding '" + img->encoding + "' not supported (mono8, bgr8, rgb8)");
      return;
    }
    if (img->data.size() < static_cast<std::size_t>(img->step) * img->height) {
      publish_status(img->header, "error: image data shorter than step x height");
      return;
    }
    std::string error;
    if (!tracker_->track(img->data.data(), static_cast<int>(img->width), static_cast<int>(img->height),
                         static_cast<int>(img->step), format, img->header.stamp.toSec(), out_, error)) {
      publish_status(img->header, "waiting: " + error);
      return;
    }
    pose_msg_.header = img->header;
    pose_msg_.pose.pose.position.x = out_.pose.t[0];
    pose_msg_.pose.pose.position.y = out_.pose.t[1];
    pose_msg_.pose.pose.position.z = out_.pose.t[2];
    pose_msg_.pose.pose.orientation.w = out_.pose.q[0];
    pose_msg_.pose.pose.orientation.x = out_.pose.q[1];
    pose_msg_.pose.pose.orientation.y = out_.pose.q[2];
    pose_msg_.pose.pose.orientation.z = out_.pose.q[3];
    // v4r's covariance is on the left tangent (v, w): x y z then rotation about x y z, ROS's order.
    std::copy(out_.covariance.begin(), out_.covariance.end(), pose_msg_.pose.covariance.begin());
    pose_pub_.publish(pose_msg_);

    transform_msg_.header = img->header;
    transform_msg_.child_frame_id = object_;
    transform_msg_.transform.translation.x = out_.pose.t[0];
    transform_msg_.transform.translation.y = out_.pose.t[1];
    transform_msg_.transform.translation.z = out_.pose.t[2];
    transform_msg_.transform.rotation = pose_msg_.pose.pose.orientation;
    transform_pub_.publish(transform_msg_);
    tf_.sendTransform(transform_msg_);
    latency_.add(std::chrono::duration<double, std::milli>(Clock::now() - received).count());
    publish_status(img->header, out_.status);
  }

  void publish_status(const std_msgs::Header& header, const std::string& text) {
    (void)header;
    status_msg_.data = text;
    status_pub_.publish(status_msg_);
  }

  std::unique_ptr<v4r::embed::ObjectTracker> tracker_;
  std::string object_;
  ros::Publisher pose_pub_, transform_pub_, status_pub_;
  ros::Subscriber info_sub_, image_sub_, hint_sub_;
  tf2_ros::TransformBroadcaster tf_;
  v4r::embed::TrackOutput out_;
  geometry_msgs::PoseWithCovarianceStamped pose_msg_;
  geometry_msgs::TransformStamped transform_msg_;
  std_msgs::String status_msg_;
  LatencyLog latency_;
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "v4r_tracker");
  ros::NodeHandle nh, pnh("~");
  v4r::embed::TrackerOptions opt;
  std::string init_pose, object = "object";
  int queue_size = 1;
  if (!pnh.getParam("model", opt.model)) {
    ROS_FATAL("v4r_ros1: the private parameter ~model (path of a .cao or mesh file) is required");
    return 1;
  }
  pnh.param<std::string>("config", opt.config, "");
  pnh.param<double>("model_scale", opt.model_scale, 1.0);
  pnh.param<std::string>("init_pose", init_pose, "");
  pnh.param<std::string>("object", object, "object");
  pnh.param<int>("queue_size", queue_size, 1);
  if (queue_size < 1 || queue_size > 1000) {
    ROS_FATAL("v4r_ros1: ~queue_size must be in [1, 1000], got %d", queue_size);
    return 1;
  }
  std::string error;
  auto tracker = v4r::embed::ObjectTracker::create(opt, error);
  if (!tracker) {
    ROS_FATAL("v4r_ros1: %s", error.c_str());
    return 1;
  }
  if (!init_pose.empty()) {
    v4r::embed::Pose p;
    if (!v4r::embed::parse_pose(init_pose, p, error)) {
      ROS_FATAL("v4r_ros1: ~init_pose: %s", error.c_str());
      return 1;
    }
    tracker->set_pose(p);
  }
  {
    TrackerNode node(nh, pnh, std::move(tracker), object, queue_size);
    ROS_INFO("v4r_ros1: tracking '%s' (model %s)%s", object.c_str(), opt.model.c_str(),
             init_pose.empty() ? "; waiting for object_position_hint" : "");
    ros::spin();
  }
  return 0;
}
