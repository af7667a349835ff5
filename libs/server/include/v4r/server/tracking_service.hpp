// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include <opencv2/core.hpp>

#include "v4r/core/clock.hpp"
#include "v4r/core/expected.hpp"
#include "v4r/core/params.hpp"
#include "v4r/filter/pose_filter.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/model.hpp"
#include "v4r/pipeline/vision_cycle.hpp"
#include "v4r/protocol/protocol.hpp"
#include "v4r/scene/scene.hpp"
#include "v4r/server/feature_model.hpp"
#include "v4r/server/outbox.hpp"
#include "v4r/server/path_policy.hpp"
#include "v4r/server/service_search.hpp"

namespace v4r::server {

/// \brief An object the service starts with (`v4r serve --scene`: the scene file's objects).
struct StartObject {
  std::string name;
  std::shared_ptr<const model::Model> model;
  geometry::SE3 T_ref_obj;  ///< its start pose in the reference frame
  bool has_pose = true;     ///< false: no start pose, the object is searched for (as without SetPose)
  /// The scene file's `tag:`: the object's AprilTag, which starts its search (the first camera).
  std::optional<detection::TagSpec> tag;
};

/// \brief Set-up of the tracking thread.
struct ServiceOptions {
  geometry::PinholeCamera camera;  ///< calibration of the input (the scene's only camera, reference frame)
  /// `v4r serve --scene`: the scene's cameras (with T_ref_cam), one input each, in this order;
  /// empty: one camera, "camera", of calibration `camera`, which is the reference frame.
  std::vector<scene::Camera> cameras;
  /// Non-empty (with `cameras`): ObjectPose names it (`ref=`), SystemStatus reports per camera.
  std::string reference_frame;
  std::vector<StartObject> objects;  ///< tracked from the first frame (AddObject + AddModel + SetPose if it has a pose)
  double fps = 30.0;               ///< frames per second the input is played at; <= 0: as fast as processed
  bool paused = false;             ///< hold at frame 0 until Start
  pipeline::CycleParams params;    ///< initial tracker parameters
  pipeline::ObjectSearchParams search;  ///< search.*: objects without a pose, and lost ones, are searched (issue 10)
  detection::DetectorParams detect;     ///< detect.*: the search's detector
  std::string cache_dir;                ///< the detector's template cache (empty: the default)
  std::string default_log_file = "v4r_cycles.csv";  ///< `Log on` without file= (the operator's file)
  PathPolicy log_dirs;             ///< where `Log on file=` may write (empty: refused)
  std::size_t max_objects = 64;    ///< AddObject beyond this: ERR code=busy
  std::size_t max_features = 10000;  ///< AddFeature beyond this many features per object: ERR code=busy
  /// Test seam (never set by a client or the command line): called with each tracked object's
  /// name at the start of its measurement on the tracking thread; whatever it throws is a fault
  /// in that object's cycle.
  std::function<void(const std::string& object)> object_hook;
  /// Test seam (never set by a client or the command line): called on the search's worker
  /// (search.background) with its stop token after it took a frame, before it searches it.
  pipeline::BackgroundSearch::Hook search_hook;
};

/// \brief Everything one frame produced for the clients, formatted once and shared by all of them.
struct FrameEvents {
  std::int64_t frame = 0;          ///< input frame index, from 0
  double stamp_s = 0.0;            ///< time stamp of the frame, seconds
  Clock::time_point released;      ///< when the frame was handed to the vision cycle
  std::vector<protocol::ObjectPoseEvent> poses;  ///< one per tracked object
  std::vector<SharedLine> pose_lines;            ///< the same, formatted (with LF)
  protocol::SystemStatusEvent status;
  SharedLine status_line;                        ///< formatted (with LF)
  double visibility_ms = 0.0, track_ms = 0.0, solve_ms = 0.0;  ///< stage times of the cycle
};

/// \brief A model parsed away from the tracking thread, to be given to an object (the second half
/// of `AddModel`).
struct ModelReady {
  std::string object;
  std::shared_ptr<const model::Model> model;
};

/// \brief The tracking thread and the one interface between the server and the pipeline. It owns
/// the input, the Scene, the VisionCycle and its parameters: frames are read from the input and
/// paced at `fps` (steady clock, sleep_until), run through the vision cycle, and each frame's
/// events are handed to the frame callback. Scene commands (objects, models, features, poses,
/// parameters, Start/Pause, Display, Log) are queued by any thread with submit() and applied by
/// the tracking thread between frames, in order; each one's reply line is handed to its callback
/// once it was applied. The tracking thread never waits for anything but the frame clock and the
/// command queue; callbacks must not block.
///
/// Play state: with `paused` the service holds before frame 0 until Start. Pause holds before
/// the next frame (the last one is not processed again, no events are sent). At the end of the
/// input the service stops producing events and keeps applying commands.
///
/// Faults: a throw in one object's cycle marks that object failed (status=failed with its last
/// pose and a growing covariance, SystemStatus failed=N, logged) until SetPose or AddModel; a
/// throw elsewhere in a frame skips that frame, in a command answers it `ERR ... code=internal`,
/// in the overlay drops that picture. Whatever escapes ends the thread through a top-level
/// handler that logs it and answers every waiting command (healthy() turns false).
class TrackingService {
 public:
  using ReplyFn = std::function<void(std::string)>;  ///< receives the reply line (without LF)
  using FrameFn = std::function<void(std::shared_ptr<const FrameEvents>)>;
  using OverlayFn = std::function<void(std::shared_ptr<const cv::Mat>, std::int64_t frame)>;
  using Request = std::variant<protocol::Command, ModelReady>;

  TrackingService(ServiceOptions opt, std::unique_ptr<io::FrameSource> source);
  /// One input per camera of `opt.cameras` (in that order), read in step: frame k of every input
  /// makes frame k of the service.
  TrackingService(ServiceOptions opt, std::vector<std::unique_ptr<io::FrameSource>> sources);
  ~TrackingService();
  TrackingService(const TrackingService&) = delete;
  TrackingService& operator=(const TrackingService&) = delete;

  /// Reads the first frame (of every input) and checks it against the calibration. Call once, before start().
  Expected<void> open();
  /// Callbacks, called on the tracking thread; set before start().
  void set_frame_callback(FrameFn fn) { on_frame_ = std::move(fn); }
  void set_overlay_callback(OverlayFn fn) { on_overlay_ = std::move(fn); }

  /// Starts the tracking thread.
  void start();
  /// Stops and joins the tracking thread (also done by the destructor).
  void stop();

  /// Queues a command for the tracking thread (thread-safe, never blocks for long). Commands the
  /// service does not handle (Subscribe, Ping, Auth...) get `ERR ... code=internal`.
  void submit(Request request, ReplyFn done);

  /// Frames processed so far.
  [[nodiscard]] std::int64_t frames_processed() const { return frames_.load(); }
  [[nodiscard]] bool paused() const { return paused_.load(); }
  [[nodiscard]] bool end_of_input() const { return end_.load(); }
  [[nodiscard]] bool display() const { return display_.load(); }
  /// Number of objects currently tracked (with a model and a pose).
  [[nodiscard]] int objects_tracked() const { return tracked_.load(); }
  /// Number of objects whose cycle failed (reported with status=failed until SetPose or AddModel).
  [[nodiscard]] int objects_failed() const { return failed_.load(); }
  /// Faults outside any one object's cycle (a frame, an overlay, a command) that were caught.
  [[nodiscard]] std::uint64_t faults() const { return faults_.load(); }
  /// False once the tracking thread stopped after an error it could not recover from.
  [[nodiscard]] bool healthy() const { return healthy_.load(); }
  /// The search (null with search.enabled false); its counters are for tests and benchmarks.
  [[nodiscard]] const ServiceSearch* search() const { return search_.get(); }

 private:
  struct ObjectEntry {
    std::string name;
    std::shared_ptr<const model::Model> model;  ///< null until AddModel or the first line/circle
    bool from_features = false;                 ///< built with AddFeature
    FeatureModel features;
    bool dirty = false;                         ///< features changed: rebuild before the next frame
    bool has_pose = false;
    geometry::SE3 pose;  ///< last SetPose (T_cam_obj), applied when the model arrives
    bool failed = false;       ///< its cycle threw: out of the scene until SetPose or AddModel
    std::string error;         ///< what it threw
    /// A pose that is held (lost, failed): the filter that predicts its covariance from the time
    /// the hold began (used when the scene's filter does not run for it).
    filter::PoseFilter hold;
    double hold_stamp = -1.0;  ///< seconds; < 0: not holding
    geometry::SE3 held_pose;   ///< T_cam_obj when it failed
  };
  struct Pending {
    Request request;
    ReplyFn done;
  };

  void run(std::stop_token st);
  void loop(std::stop_token st);
  void apply_pending();
  std::string apply(const Request& r);
  std::string apply_command(const protocol::Command& c);
  std::string set_model(ObjectEntry& e, std::shared_ptr<const model::Model> m, std::string_view cmd);
  void load_next_frame();
  Expected<bool> read_in_step();
  void add_start_objects();
  [[nodiscard]] std::vector<protocol::CameraStatus> camera_status() const;
  void rebuild_models();
  void process_frame(Clock::time_point released);
  void frame_cycle(Clock::time_point released);
  void object_failed(std::size_t scene_index, const std::string& error, double stamp);
  void count_objects();
  [[nodiscard]] geometry::SE3 T_out_ref() const;
  [[nodiscard]] geometry::Matrix6d published_covariance(const scene::Object& o) const;
  void publish_overlay(const pipeline::CycleReport& rep, std::int64_t index);
  ObjectEntry* find(const std::string& name);

  // Command handlers: return the reply line.
  std::string on(const protocol::AddObject& c);
  std::string on(const protocol::RemoveObject& c);
  std::string on(const protocol::AddJunction& c);
  std::string on(const protocol::AddLine& c);
  std::string on(const protocol::AddCircle& c);
  std::string on(const protocol::RemoveFeature& c);
  std::string on(const protocol::SetPose& c);
  std::string on(const protocol::SetParam& c);
  std::string on(const protocol::GetParam& c);
  std::string on(const protocol::ListParams& c);
  std::string on(const protocol::Start& c);
  std::string on(const protocol::Pause& c);
  std::string on(const protocol::Display& c);
  std::string on(const protocol::Log& c);
  std::string feature_changed(ObjectEntry& e, const char* cmd, const std::string& id, Expected<void> r);

  ServiceOptions opt_;
  std::vector<std::unique_ptr<io::FrameSource>> sources_;  ///< one per camera of the scene
  FrameFn on_frame_;
  OverlayFn on_overlay_;

  // Owned by the tracking thread.
  scene::Scene scene_;
  pipeline::CycleParams params_;
  ParamRegistry registry_;
  pipeline::VisionCycle cycle_;
  std::vector<ObjectEntry> objects_;
  std::vector<cv::Mat> frames_in_, greys_;     ///< per camera: the frame read, in grey
  std::vector<std::int64_t> camera_frames_;    ///< per camera: frames read from its input
  std::vector<char> camera_alive_;             ///< per camera: its input still delivers frames
  bool have_frame_ = false;
  std::int64_t next_frame_ = 0;
  double first_capture_s_ = -1.0;  ///< live input: capture time of the first frame (steady clock, s)
  Clock::time_point due_;
  std::FILE* log_ = nullptr;

  std::mutex mutex_;  // guards queue_
  std::condition_variable_any wake_;
  std::deque<Pending> queue_;

  std::atomic<std::int64_t> frames_{0};
  std::atomic<bool> paused_{false}, end_{false}, display_{false};
  std::atomic<int> tracked_{0}, failed_{0};
  std::atomic<std::uint64_t> faults_{0};
  std::atomic<bool> healthy_{true};
  std::unique_ptr<ServiceSearch> search_;  // null: search.enabled is false
  std::jthread thread_;
};

}  // namespace v4r::server
