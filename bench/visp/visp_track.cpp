// v4r - reference runs of ViSP's model-based edge tracker (comparison only; never linked into
// v4r, never part of the CMake build: bench/compare_visp.sh compiles it with pkg-config visp).
// ViSP is GPL; this file only calls its public API (vpMbGenericTracker, vpMe).
//
// Runs vpMbGenericTracker in EDGE_TRACKER mode (moving edges only, no KLT, no depth) over a
// sequence in the format of the shared benchmark and writes one CSV row per frame:
//   frame,tx,ty,tz,qw,qx,qy,qz,cycle_ms,status        (T_cam_obj, metres; status tracking|lost)
//
// usage: visp_track --model M.cao --camera camera.yaml --input FRAMES_DIR --init-pose-file P.txt
//                   --output out.csv [--mask-size 5] [--range 7] [--threshold 5000] [--mu 0.5]
//                   [--sample-step 4] [--angle-appear 70] [--angle-disappear 80]
//                   [--near 0.05] [--far 3.0]
//   camera.yaml : OpenCV FileStorage (camera_matrix, distortion_coefficients); non-zero
//                 distortion is removed from each frame with cv::undistort before tracking.
//   P.txt       : 'tx ty tz rx ry rz' (metres, rotation vector theta*u = OpenCV Rodrigues),
//                 whitespace or newlines between the numbers (so ViSP .pos files work too).
//   FRAMES_DIR  : images sorted by file name (png, pgm, jpg, ppm, bmp).
// A frame on which ViSP throws (too few moving edges, divergence) is written with the last good
// pose and status 'lost'; the tracker is then re-initialised from that pose on the next frame,
// as a user of ViSP would do.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <visp3/core/vpCameraParameters.h>
#include <visp3/core/vpException.h>
#include <visp3/core/vpHomogeneousMatrix.h>
#include <visp3/core/vpImage.h>
#include <visp3/core/vpImageConvert.h>
#include <visp3/core/vpPolygon3D.h>
#include <visp3/core/vpQuaternionVector.h>
#include <visp3/core/vpRotationMatrix.h>
#include <visp3/core/vpThetaUVector.h>
#include <visp3/core/vpTranslationVector.h>
#include <visp3/klt/vpKltOpencv.h>
#include <visp3/mbt/vpMbGenericTracker.h>
#include <visp3/me/vpMe.h>

namespace fs = std::filesystem;

namespace {

struct Options {
  std::string model, camera, input, init_pose, output;
  // Moving-edge settings as a ViSP user takes them: the values of the configuration ViSP ships
  // with its cube sequence (visp-images-data mbt/cube.xml): 5x5 masks in 180 orientations
  // (2 deg), search +-7 px along the edge normal, likelihood threshold 5000, contrast
  // continuity mu1 = mu2 = 0.5, a sample every 4 px. On that real cube ViSP is sensitive to
  // these: range 10, or faces appearing/disappearing at 65/75 deg, make it flip a face at
  // frames ~185-217; range 7 with 70/80 deg tracks all 218 frames (checked on an overlay).
  unsigned mask_size = 5, mask_number = 180, range = 7;
  double threshold = 5000.0, mu = 0.5, sample_step = 4.0;
  // Face visibility (degrees between the face normal and the line of sight; ViSP's own
  // defaults 70/80), near/far clipping (metres; the benchmark's objects are at 0.3-2 m).
  double angle_appear = 70.0, angle_disappear = 80.0, near_clip = 0.05, far_clip = 3.0;
  // --klt: moving edges and KLT points on the faces (EDGE_TRACKER | KLT_TRACKER), KLT settings of
  // ViSP's own cube configuration (mbt/cube.xml): 300 features, window 5, quality 0.01,
  // min distance 5, Harris 0.01, block 3, 3 pyramid levels, mask border 5.
  bool klt = false;
};

[[noreturn]] void die(const std::string& msg) {
  std::cerr << "visp_track: error: " << msg << "\n";
  std::exit(2);
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) die("option " + a + " needs a value");
      return argv[++i];
    };
    auto number = [&]() {
      const std::string v = value();
      char* end = nullptr;
      const double d = std::strtod(v.c_str(), &end);
      if (end == v.c_str() || *end != '\0') die("option " + a + ": not a number: '" + v + "'");
      return d;
    };
    if (a == "--model") o.model = value();
    else if (a == "--camera") o.camera = value();
    else if (a == "--input") o.input = value();
    else if (a == "--init-pose-file") o.init_pose = value();
    else if (a == "--output") o.output = value();
    else if (a == "--mask-size") o.mask_size = static_cast<unsigned>(number());
    else if (a == "--range") o.range = static_cast<unsigned>(number());
    else if (a == "--threshold") o.threshold = number();
    else if (a == "--sample-step") o.sample_step = number();
    else if (a == "--angle-appear") o.angle_appear = number();
    else if (a == "--angle-disappear") o.angle_disappear = number();
    else if (a == "--mu") o.mu = number();
    else if (a == "--near") o.near_clip = number();
    else if (a == "--far") o.far_clip = number();
    else if (a == "--klt") o.klt = true;
    else if (a == "--help" || a == "-h") {
      std::cout << "usage: visp_track --model M.cao --camera camera.yaml --input FRAMES --init-pose-file P.txt "
                   "--output out.csv [--mask-size N] [--range PX] [--threshold T] [--sample-step PX] "
                   "[--mu M] [--angle-appear DEG] [--angle-disappear DEG] [--near M] [--far M] [--klt]\n";
      std::exit(0);
    } else {
      die("unknown option '" + a + "'");
    }
  }
  if (o.model.empty() || o.camera.empty() || o.input.empty() || o.init_pose.empty() || o.output.empty())
    die("--model, --camera, --input, --init-pose-file and --output are required (see --help)");
  return o;
}

std::vector<std::string> list_frames(const std::string& dir) {
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext == ".png" || ext == ".pgm" || ext == ".jpg" || ext == ".jpeg" || ext == ".ppm" || ext == ".bmp")
      files.push_back(e.path().string());
  }
  if (ec) die("cannot list " + dir + ": " + ec.message());
  std::sort(files.begin(), files.end());
  if (files.empty()) die("no images in " + dir);
  return files;
}

vpHomogeneousMatrix read_pose(const std::string& path) {
  std::ifstream in(path);
  if (!in) die("cannot open " + path);
  double v[6];
  for (double& x : v)
    if (!(in >> x)) die(path + ": expected 6 numbers 'tx ty tz rx ry rz'");
  return vpHomogeneousMatrix(vpTranslationVector(v[0], v[1], v[2]), vpThetaUVector(v[3], v[4], v[5]));
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);

  cv::FileStorage fsr(o.camera, cv::FileStorage::READ);
  if (!fsr.isOpened()) die("cannot open camera file " + o.camera);
  cv::Mat K, dist;
  fsr["camera_matrix"] >> K;
  fsr["distortion_coefficients"] >> dist;
  if (K.rows != 3 || K.cols != 3) die(o.camera + ": camera_matrix must be 3x3");
  K.convertTo(K, CV_64F);
  const bool distorted = !dist.empty() && cv::countNonZero(dist != 0) > 0;
  vpCameraParameters cam(K.at<double>(0, 0), K.at<double>(1, 1), K.at<double>(0, 2), K.at<double>(1, 2));

  const std::vector<std::string> frames = list_frames(o.input);
  vpHomogeneousMatrix cMo = read_pose(o.init_pose);

  vpMe me;
  me.setMaskSize(o.mask_size);
  me.setMaskNumber(o.mask_number);
  me.setRange(o.range);
  me.setThreshold(o.threshold);
  me.setMu1(o.mu);
  me.setMu2(o.mu);
  me.setSampleStep(o.sample_step);

  vpMbGenericTracker tracker(1, o.klt ? (vpMbGenericTracker::EDGE_TRACKER | vpMbGenericTracker::KLT_TRACKER)
                                      : vpMbGenericTracker::EDGE_TRACKER);
  try {
    if (o.klt) {
      vpKltOpencv klt;
      klt.setMaxFeatures(300);
      klt.setWindowSize(5);
      klt.setQuality(0.01);
      klt.setMinDistance(5);
      klt.setHarrisFreeParameter(0.01);
      klt.setBlockSize(3);
      klt.setPyramidLevels(3);
      tracker.setKltOpencv(klt);
      tracker.setKltMaskBorder(5);
    }
    tracker.setCameraParameters(cam);
    tracker.setMovingEdge(me);
    tracker.setAngleAppear(vpMath::rad(o.angle_appear));
    tracker.setAngleDisappear(vpMath::rad(o.angle_disappear));
    tracker.setNearClippingDistance(o.near_clip);
    tracker.setFarClippingDistance(o.far_clip);
    tracker.setClipping(vpPolygon3D::NEAR_CLIPPING | vpPolygon3D::FAR_CLIPPING);
    tracker.loadModel(o.model);
  } catch (const vpException& e) {
    die("ViSP cannot set up the tracker with " + o.model + ": " + e.getStringMessage());
  }

  std::ofstream out(o.output);
  if (!out) die("cannot write " + o.output);
  out << "frame,tx,ty,tz,qw,qx,qy,qz,cycle_ms,status\n";
  out.precision(9);

  vpImage<unsigned char> I;
  cv::Mat grey, undist;
  vpHomogeneousMatrix last_good = cMo;
  bool reinit = true;  // frame 0: initialise from the given pose
  int lost = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    grey = cv::imread(frames[k], cv::IMREAD_GRAYSCALE);
    if (grey.empty()) die("cannot read image " + frames[k]);
    if (distorted) {
      cv::undistort(grey, undist, K, dist);
      grey = undist;
    }
    vpImageConvert::convert(grey, I);
    std::string status = "tracking";
    const auto t0 = std::chrono::steady_clock::now();
    try {
      if (reinit) {
        tracker.initFromPose(I, last_good);
        reinit = false;
      }
      if (k > 0) tracker.track(I);
      tracker.getPose(cMo);
      last_good = cMo;
    } catch (const vpException& e) {
      status = "lost";
      cMo = last_good;
      reinit = true;
      ++lost;
    }
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const vpTranslationVector t = cMo.getTranslationVector();
    const vpQuaternionVector q(cMo.getRotationMatrix());
    out << k << ',' << t[0] << ',' << t[1] << ',' << t[2] << ',' << q.w() << ',' << q.x() << ',' << q.y() << ','
        << q.z() << ',' << ms << ',' << status << '\n';
  }
  std::cerr << "visp_track: " << frames.size() << " frames, " << lost << " lost -> " << o.output << "\n";
  return 0;
}
