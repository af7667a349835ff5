// v4r - robust model-based object tracking. MIT licence.
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <new>
#include <random>

#include <gtest/gtest.h>

#include "v4r/filter/pose_filter.hpp"

// The replaced operator new uses malloc and operator delete uses free, consistently; GCC cannot
// see that through inlined standard-library code.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

// Counting global allocator: lets a test prove that the filter never allocates.
namespace {
std::atomic<long> g_allocations{0};
}  // namespace
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, std::align_val_t a) {
  ++g_allocations;
  const std::size_t al = static_cast<std::size_t>(a);
  if (void* p = std::aligned_alloc(al, (n + al - 1) / al * al)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) { return operator new(n, a); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

using namespace v4r::filter;
using v4r::geometry::Matrix6d;
using v4r::geometry::SE3;
using v4r::geometry::Vector6d;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDt = 1.0 / 30.0;
constexpr double kSigmaT = 0.001;                  ///< measurement noise, metres per axis
constexpr double kSigmaR = 0.2 * kPi / 180.0;      ///< measurement noise, radians per axis

Vector6d random_twist(std::mt19937& rng, double t_scale, double r_scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vector6d xi;
  for (int i = 0; i < 3; ++i) xi[i] = t_scale * u(rng);
  for (int i = 3; i < 6; ++i) xi[i] = r_scale * u(rng);
  return xi;
}

/// \brief A noisy pose measurement and its covariance in the left tangent.
struct Measurement {
  SE3 T;
  Matrix6d cov;
};

/// Left-tangent covariance of a pose measured with independent noise of kSigmaT per axis on the
/// object position and kSigmaR per axis on the rotation about the object origin:
/// T_meas = (R_e R, t + e_t), so log(T_meas T^-1) ~= (e_t + hat(t) e_r, e_r).
/// `scale` multiplies both sigmas.
Matrix6d measurement_cov(const SE3& T, double scale = 1.0) {
  Matrix6d A = Matrix6d::Identity();
  A.topRightCorner<3, 3>() = v4r::geometry::hat(T.translation());
  const double st = scale * kSigmaT, sr = scale * kSigmaR;
  Matrix6d D = Matrix6d::Zero();
  D.diagonal() << st * st, st * st, st * st, sr * sr, sr * sr, sr * sr;
  return A * D * A.transpose();
}

/// The truth measured with the noise of measurement_cov(T, scale).
Measurement measure(std::mt19937& rng, const SE3& T, double scale = 1.0) {
  std::normal_distribution<double> n(0.0, scale);
  const Eigen::Vector3d e_t(kSigmaT * n(rng), kSigmaT * n(rng), kSigmaT * n(rng));
  const Eigen::Vector3d e_r(kSigmaR * n(rng), kSigmaR * n(rng), kSigmaR * n(rng));
  const SE3 Z(Eigen::Matrix3d(v4r::geometry::so3_exp(e_r) * T.rotation()), Eigen::Vector3d(T.translation() + e_t));
  return {Z, measurement_cov(Z, scale)};
}

/// SE(3) log accurate for every rotation angle: the reference for the numeric derivatives below
/// (SE3::log loses digits for angles of ~1e-6 to 1e-4 rad, where 1 - cos(angle) cancels).
Vector6d log_ref(const SE3& T) {
  const Eigen::AngleAxisd aa(T.quaternion());
  const Eigen::Vector3d w = aa.angle() * aa.axis();
  const double th = aa.angle();
  const Eigen::Matrix3d W = v4r::geometry::hat(w);
  // V^-1 = I - W / 2 + k W^2, k = (1 - (th / 2) cot(th / 2)) / th^2.
  const double k = th < 1e-4 ? 1.0 / 12.0 + th * th / 720.0 : (1.0 - 0.5 * th / std::tan(0.5 * th)) / (th * th);
  Vector6d xi;
  xi.head<3>() = (Eigen::Matrix3d::Identity() - 0.5 * W + k * W * W) * T.translation();
  xi.tail<3>() = w;
  return xi;
}

/// Left-tangent error (m, rad) of an estimate.
Vector6d error(const SE3& est, const SE3& truth) { return log_ref(est * truth.inverse()); }
/// Position error of the object origin, metres.
double pos_error(const SE3& est, const SE3& truth) { return (est.translation() - truth.translation()).norm(); }
/// Rotation error, radians.
double rot_error(const SE3& est, const SE3& truth) { return v4r::geometry::rotation_angle_between(est, truth); }

SE3 start_pose() { return SE3::from_rvec({0.05, -0.02, 0.7}, {0.3, -0.5, 0.2}); }

/// A measurement of `truth` with independent Gaussian noise of covariance diag(R) (left tangent).
SE3 noisy_measurement(const SE3& truth, const Matrix6d& R, std::mt19937& rng, std::normal_distribution<double>& g) {
  Vector6d e;
  for (int i = 0; i < 6; ++i) e[i] = g(rng) * std::sqrt(R(i, i));
  return SE3::exp(e) * truth;
}

}  // namespace

TEST(PoseFilter, ReferenceLogInvertsExp) {
  std::mt19937 rng(0);
  for (int k = 0; k < 300; ++k) {
    const double r_scale = std::pow(10.0, -8.0 + 8.0 * (k % 10) / 9.0);  // 1e-8 .. 1 rad
    const Vector6d xi = random_twist(rng, 0.5, r_scale);
    // SE3::exp itself loses ~1e-11 to cancellation in 1 - cos for angles near 1e-6 rad.
    EXPECT_LT((log_ref(SE3::exp(xi)) - xi).norm(), 1e-10) << "|w| " << xi.tail<3>().norm();
  }
}

TEST(PoseFilter, SE3LeftJacobianAndAdjointMatchDefinitions) {
  std::mt19937 rng(1);
  const double h = 1e-6;
  for (int k = 0; k < 200; ++k) {
    // Small and large rotations, including the series branch.
    const double r_scale = k % 3 == 0 ? 1e-3 : (k % 3 == 1 ? 0.05 : 2.0);
    const Vector6d xi = random_twist(rng, 0.5, r_scale);
    const SE3 E = SE3::exp(xi);
    Matrix6d Jn, An;
    for (int c = 0; c < 6; ++c) {
      Vector6d d = Vector6d::Zero();
      d[c] = h;
      // exp(xi + d) exp(xi)^-1 = exp(J_l d).
      Jn.col(c) = (log_ref(SE3::exp(xi + d) * E.inverse()) - log_ref(SE3::exp(xi - d) * E.inverse())) / (2 * h);
      // E exp(d) E^-1 = exp(Ad d).
      An.col(c) = (log_ref(E * SE3::exp(d) * E.inverse()) - log_ref(E * SE3::exp(-d) * E.inverse())) / (2 * h);
    }
    EXPECT_LT((v4r::geometry::left_jacobian(xi) - Jn).norm(), 1e-7) << "k " << k << " |w| " << xi.tail<3>().norm();
    EXPECT_LT((v4r::geometry::adjoint(E) - An).norm(), 1e-7) << "k " << k;
  }
  EXPECT_LT((v4r::geometry::left_jacobian(Vector6d::Zero()) - Matrix6d::Identity()).norm(), 1e-15);
}

TEST(PoseFilter, TransitionJacobianMatchesNumericPropagation) {
  // Propagate a perturbed state (T = exp(xi) T0, vel = vel0 + dvel) exactly and compare the
  // resulting error state with F * (xi, dvel).
  std::mt19937 rng(2);
  const double h = 1e-6;
  for (int k = 0; k < 100; ++k) {
    const SE3 T0 = SE3::exp(random_twist(rng, 0.5, 2.0));
    const Vector6d vel0 = random_twist(rng, 0.5, 3.0);
    const double dt = k % 2 == 0 ? kDt : 0.3;
    const SE3 T1 = SE3::exp(vel0 * dt) * T0;
    const auto propagate = [&](const Vector12d& d) {
      const SE3 T = SE3::exp(d.head<6>()) * T0;
      const Vector6d vel = vel0 + d.tail<6>();
      Vector12d out;
      out.head<6>() = log_ref(SE3::exp(vel * dt) * T * T1.inverse());
      out.tail<6>() = vel - vel0;
      return out;
    };
    Matrix12d Fn;
    for (int c = 0; c < 12; ++c) {
      Vector12d d = Vector12d::Zero();
      d[c] = h;
      Fn.col(c) = (propagate(d) - propagate(-d)) / (2 * h);
    }
    const Matrix12d F = PoseFilter::transition_jacobian(vel0, dt);
    EXPECT_LT((F - Fn).norm(), 1e-6) << "k " << k;
  }
  // dt = 0: identity.
  EXPECT_EQ(PoseFilter::transition_jacobian(random_twist(rng, 1.0, 1.0), 0.0), Matrix12d::Identity());
}

TEST(PoseFilter, SmoothsConstantVelocityMotionAndEstimatesVelocity) {
  // Truth: constant twist; measurements: 1 mm on the position and 0.2 deg on the rotation per
  // axis, at 30 Hz, 10 s.
  Vector6d vel_true;
  vel_true << 0.10, -0.05, 0.08, 0.3, 0.2, -0.4;  // m/s, rad/s
  PoseFilterParams smooth;
  smooth.accel_noise = 0.05;  // the motion really is smooth
  smooth.angular_accel_noise = 0.05;
  for (const bool tuned : {true, false}) {
    PoseFilter f(tuned ? smooth : PoseFilterParams{});
    std::mt19937 rng(3);
    SE3 T = start_pose();
    constexpr int kFrames = 300, kSkip = 60;
    double sum_meas_t = 0, sum_filt_t = 0, sum_meas_r = 0, sum_filt_r = 0, nees = 0;
    int n = 0;
    for (int k = 0; k < kFrames; ++k) {
      if (k > 0) {
        T = SE3::exp(vel_true * kDt) * T;
        f.predict(kDt);
      }
      const Measurement z = measure(rng, T);
      EXPECT_TRUE(std::isfinite(f.update(z.T, z.cov)));
      if (k < kSkip) continue;
      sum_meas_t += std::pow(pos_error(z.T, T), 2);
      sum_filt_t += std::pow(pos_error(f.pose(), T), 2);
      sum_meas_r += std::pow(rot_error(z.T, T), 2);
      sum_filt_r += std::pow(rot_error(f.pose(), T), 2);
      const Vector6d e = error(f.pose(), T);
      nees += e.dot(f.pose_covariance().ldlt().solve(e));
      ++n;
    }
    const double ratio_t = std::sqrt(sum_filt_t / sum_meas_t), ratio_r = std::sqrt(sum_filt_r / sum_meas_r);
    const Vector6d ve = f.velocity() - vel_true;
    const double rel_v = ve.head<3>().norm() / vel_true.head<3>().norm();
    const double rel_w = ve.tail<3>().norm() / vel_true.tail<3>().norm();
    // Velocity of the object origin, v + w x t (the left twist's v is that of the camera origin).
    const Eigen::Vector3d c_dot_true = vel_true.head<3>() + vel_true.tail<3>().cross(T.translation());
    const Eigen::Vector3d c_dot = f.velocity().head<3>() + f.velocity().tail<3>().cross(f.pose().translation());
    const double rel_c = (c_dot - c_dot_true).norm() / c_dot_true.norm();
    std::printf("[constant velocity, %s] filtered/measured RMS: position %.3f, rotation %.3f; velocity error: "
                "twist v %.1f %%, w %.1f %%, object origin %.1f %%; mean NEES %.2f (6)\n",
                tuned ? "smooth model" : "default model", ratio_t, ratio_r, 100 * rel_v, 100 * rel_w, 100 * rel_c,
                nees / n);
    if (tuned) {
      EXPECT_LT(ratio_t, 0.7);
      EXPECT_LT(ratio_r, 0.7);
      // The twist's v is the velocity of the camera origin carried along, v = c_dot - w x t: the
      // angular velocity error enters it with the lever arm |t| = 0.75 m (~2.5 x |v| here).
      EXPECT_LT(rel_v, 0.1);
      EXPECT_LT(rel_w, 0.1);
      EXPECT_LT(rel_c, 0.1);
      EXPECT_GT(nees / n, 3.0);
      EXPECT_LT(nees / n, 9.0);
    } else {
      // Agile default model: less smoothing, but better than the raw measurements.
      EXPECT_LT(ratio_t, 0.95);
      EXPECT_LT(ratio_r, 0.95);
    }
  }
}

TEST(PoseFilter, IsConsistentWhenTheMotionMatchesTheModel) {
  // Truth driven by the filter's own process model (white acceleration noise, default levels)
  // sampled finely; the average NEES of the filtered pose must be ~6.
  PoseFilterParams p;
  std::mt19937 rng(4);
  std::normal_distribution<double> n01(0.0, 1.0);
  PoseFilter f(p);
  SE3 T = start_pose();
  Vector6d vel = Vector6d::Zero();
  constexpr int kSub = 20, kFrames = 600;
  double nees = 0;
  int n = 0;
  for (int k = 0; k < kFrames; ++k) {
    if (k > 0) {
      const double h = kDt / kSub;
      for (int s = 0; s < kSub; ++s) {
        T = SE3::exp(vel * h) * T;
        // Object-centred white acceleration: dv = a + hat(t) alpha (left twist), dw = alpha.
        Vector6d a;
        for (int i = 0; i < 6; ++i)
          a[i] = (i < 3 ? p.accel_noise : p.angular_accel_noise) * std::sqrt(p.reference_dt * h) * n01(rng);
        vel.head<3>() += a.head<3>() + T.translation().cross(a.tail<3>());
        vel.tail<3>() += a.tail<3>();
      }
      f.predict(kDt);
    }
    const Measurement z = measure(rng, T);
    f.update(z.T, z.cov);
    if (k < 30) continue;
    const Vector6d e = error(f.pose(), T);
    nees += e.dot(f.pose_covariance().ldlt().solve(e));
    ++n;
  }
  std::printf("[model-matched motion] mean NEES %.2f (expect 6)\n", nees / n);
  EXPECT_GT(nees / n, 4.5);
  EXPECT_LT(nees / n, 7.5);
}

TEST(PoseFilter, PredictionBeatsConstantPoseOnSmoothMotion) {
  // A smoothly moving object: sinusoidal translation (15 cm, 0.25 Hz: up to 0.24 m/s and
  // 0.37 m/s^2) and rotation (40 deg, 0.2 Hz: up to 50 deg/s and 1.1 rad/s^2), a filter whose
  // noise levels are about those accelerations. Predict one and three frames ahead and compare
  // with "the object stays where it was last estimated".
  const auto truth = [](double t) {
    const double a = 0.5 * kPi * t, b = 0.4 * kPi * t;
    const Eigen::Vector3d pos(0.15 * std::sin(a), 0.08 * std::cos(a), 0.8 + 0.05 * std::sin(0.5 * a));
    const Eigen::Vector3d rot = (40.0 * kPi / 180.0) * std::sin(b + 0.5) * Eigen::Vector3d(0.6, 0.8, 0.0);
    return SE3(Eigen::Matrix3d(v4r::geometry::so3_exp(rot) * v4r::geometry::so3_exp({0.2, 0.1, 0.3})), pos);
  };
  PoseFilterParams p;
  p.accel_noise = 0.4;
  p.angular_accel_noise = 1.2;
  std::mt19937 rng(5);
  for (const double noise : {1.0, 0.1}) {
    for (const int ahead : {1, 3}) {
      PoseFilter f(p);
      double sum_cv = 0, sum_const = 0, sum_cv_r = 0, sum_const_r = 0;
      int n = 0;
      for (int k = 0; k < 300; ++k) {
        const double t = k * kDt;
        if (k > 0) f.predict(kDt);
        const Measurement z = measure(rng, truth(t), noise);
        f.update(z.T, z.cov);
        if (k < 30) continue;
        const SE3 target = truth(t + ahead * kDt), predicted = f.predict_pose(ahead * kDt);
        sum_cv += std::pow(pos_error(predicted, target), 2);
        sum_const += std::pow(pos_error(f.pose(), target), 2);
        sum_cv_r += std::pow(rot_error(predicted, target), 2);
        sum_const_r += std::pow(rot_error(f.pose(), target), 2);
        ++n;
      }
      const double rms_cv = std::sqrt(sum_cv / n), rms_c = std::sqrt(sum_const / n);
      const double rms_cv_r = std::sqrt(sum_cv_r / n), rms_c_r = std::sqrt(sum_const_r / n);
      std::printf("[prediction %d frame(s) ahead, noise x%.1f] RMS position: constant velocity %.2f mm, constant "
                  "pose %.2f mm (x%.1f); rotation: %.3f deg vs %.3f deg (x%.1f)\n",
                  ahead, noise, 1e3 * rms_cv, 1e3 * rms_c, rms_c / rms_cv, rms_cv_r * 180 / kPi, rms_c_r * 180 / kPi,
                  rms_c_r / rms_cv_r);
      // With 1 mm / 0.2 deg measurements the prediction is limited by the measurement noise.
      const double factor = noise < 0.5 ? (ahead == 1 ? 8.0 : 6.0) : (ahead == 1 ? 2.5 : 3.5);
      EXPECT_GT(rms_c / rms_cv, factor);
      EXPECT_GT(rms_c_r / rms_cv_r, factor);
    }
  }
}

TEST(PoseFilter, GrossMeasurementGivesLargeChi2AndGateRejectsIt) {
  // A smooth motion model (prediction uncertainty well below the measurement noise; with the
  // agile default model the prediction's own uncertainty of a few mm dilutes the chi2).
  PoseFilterParams p;
  p.accel_noise = 0.2;
  p.angular_accel_noise = 0.2;
  PoseFilter f(p);
  std::mt19937 rng(6);
  SE3 T = start_pose();
  Vector6d vel;
  vel << 0.05, 0.0, -0.02, 0.1, 0.0, 0.2;
  double sum_chi2 = 0;
  int n = 0;
  for (int k = 0; k < 100; ++k) {
    if (k > 0) {
      T = SE3::exp(vel * kDt) * T;
      f.predict(kDt);
    }
    const Measurement z = measure(rng, T);
    const double chi2 = f.update(z.T, z.cov);
    if (k >= 20) {
      sum_chi2 += chi2;
      ++n;
    }
  }
  std::printf("[innovation] mean chi2 of good measurements %.2f (6 dof)\n", sum_chi2 / n);
  EXPECT_GT(sum_chi2 / n, 4.0);
  EXPECT_LT(sum_chi2 / n, 8.0);

  // The object origin 20 sigma off along x.
  T = SE3::exp(vel * kDt) * T;
  f.predict(kDt);
  const SE3 bad(T.quaternion(), Eigen::Vector3d(T.translation() + Eigen::Vector3d(20.0 * kSigmaT, 0.0, 0.0)));
  const double chi2_bad = f.innovation_chi2(bad, measurement_cov(bad));
  // The rotation 20 sigma off about the object origin.
  const SE3 bad_r(Eigen::Matrix3d(v4r::geometry::so3_exp({0.0, 20.0 * kSigmaR, 0.0}) * T.rotation()), T.translation());
  const double chi2_bad_r = f.innovation_chi2(bad_r, measurement_cov(bad_r));
  std::printf("[innovation] 20 sigma measurement: chi2 %.1f (position), %.1f (rotation)\n", chi2_bad, chi2_bad_r);
  EXPECT_GT(chi2_bad, 100.0);
  EXPECT_GT(chi2_bad_r, 100.0);
  // Gated: state unchanged, chi2 still reported.
  const SE3 before = f.pose();
  const Matrix12d P_before = f.covariance();
  EXPECT_DOUBLE_EQ(f.update(bad, measurement_cov(bad), 16.8), chi2_bad);
  EXPECT_EQ(f.pose().matrix(), before.matrix());
  EXPECT_EQ(f.covariance(), P_before);
  // Applied without a gate it pulls the estimate.
  EXPECT_DOUBLE_EQ(f.update(bad, measurement_cov(bad)), chi2_bad);
  EXPECT_GT(pos_error(f.pose(), before), 1e-4);
}

TEST(PoseFilter, ResetAndInvalidInput) {
  PoseFilterParams p;
  p.init_velocity_sigma = 0.3;
  p.init_angular_velocity_sigma = 0.7;
  PoseFilter f(p);
  EXPECT_FALSE(f.initialised());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(f.innovation_chi2(start_pose(), measurement_cov(start_pose())), PoseFilter::kInvalidChi2);
  f.predict(kDt);  // no-op before initialisation
  EXPECT_FALSE(f.initialised());

  const Matrix6d C = measurement_cov(start_pose());
  f.reset(start_pose(), C);
  ASSERT_TRUE(f.initialised());
  EXPECT_EQ(f.pose().matrix(), start_pose().matrix());
  EXPECT_EQ(f.velocity(), Vector6d::Zero());
  EXPECT_LT((f.pose_covariance() - C).norm(), 1e-15 * C.norm());
  const Matrix12d P0 = f.covariance();
  EXPECT_DOUBLE_EQ(P0(6, 6), 0.09);
  EXPECT_DOUBLE_EQ(P0(11, 11), 0.49);
  EXPECT_EQ(P0.block(0, 6, 6, 6).cwiseAbs().maxCoeff(), 0.0);

  // Run a while, then reset: everything from before is gone.
  Vector6d vel;
  vel << 0.2, 0.1, 0.0, 0.0, 0.5, 0.0;
  SE3 T = start_pose();
  for (int k = 0; k < 50; ++k) {
    T = SE3::exp(vel * kDt) * T;
    f.predict(kDt);
    f.update(T, C);
  }
  EXPECT_GT(f.velocity().norm(), 0.3);
  const SE3 T2 = SE3::from_rvec({0.0, 0.1, 1.0}, {0.0, 0.0, 1.0});
  f.reset(T2, 4.0 * C);
  EXPECT_EQ(f.pose().matrix(), T2.matrix());
  EXPECT_EQ(f.velocity(), Vector6d::Zero());
  Matrix12d P_expected = P0;
  P_expected.topLeftCorner<6, 6>() = 4.0 * C;
  EXPECT_LT((f.covariance() - P_expected).norm(), 1e-15 * P_expected.norm());
  // reset_velocity keeps the pose.
  for (int k = 0; k < 10; ++k) {
    f.predict(kDt);
    f.update(SE3::exp(vel * kDt * (k + 1)) * T2, C);
  }
  const SE3 kept = f.pose();
  f.reset_velocity();
  EXPECT_EQ(f.pose().matrix(), kept.matrix());
  EXPECT_EQ(f.velocity(), Vector6d::Zero());
  EXPECT_EQ(f.covariance().block(0, 6, 6, 6).cwiseAbs().maxCoeff(), 0.0);

  // predict(0), negative and NaN dt change nothing; predict_pose(0) is the pose.
  const Matrix12d P = f.covariance();
  for (const double dt : {0.0, -0.1, nan, std::numeric_limits<double>::infinity()}) {
    f.predict(dt);
    EXPECT_EQ(f.pose().matrix(), kept.matrix());
    EXPECT_EQ(f.covariance(), P);
  }
  EXPECT_EQ(f.predict_pose(0.0).matrix(), kept.matrix());
  EXPECT_EQ(f.predict_pose(nan).matrix(), kept.matrix());

  // NaN measurements and covariances are ignored with a huge chi2.
  const SE3 T_nan(Eigen::Quaterniond::Identity(), Eigen::Vector3d(nan, 0.0, 0.0));
  EXPECT_EQ(f.update(T_nan, C), PoseFilter::kInvalidChi2);
  Matrix6d C_nan = C;
  C_nan(2, 3) = nan;
  EXPECT_EQ(f.update(kept, C_nan), PoseFilter::kInvalidChi2);
  // A covariance that makes S indefinite is refused too.
  EXPECT_EQ(f.update(kept, -100.0 * Matrix6d::Identity()), PoseFilter::kInvalidChi2);
  EXPECT_EQ(f.pose().matrix(), kept.matrix());
  EXPECT_EQ(f.covariance(), P);
  EXPECT_GT(PoseFilter::kInvalidChi2, 1e300);

  // Before initialisation, update() initialises.
  PoseFilter g;
  EXPECT_EQ(g.update(T2, C), 0.0);
  EXPECT_TRUE(g.initialised());
  EXPECT_EQ(g.pose().matrix(), T2.matrix());
  // A NaN reset leaves it uninitialised.
  g.reset(T_nan, C);
  EXPECT_FALSE(g.initialised());
}

TEST(PoseFilter, VariableTimeStepsAreConsistent) {
  // Two half steps and one full step give the same mean and (for the linear parts) nearly the
  // same covariance: the process noise is a density, not a per-call constant.
  PoseFilter a, b;
  Vector6d vel;
  vel << 0.1, 0.0, 0.0, 0.0, 0.0, 0.5;
  a.reset(start_pose(), measurement_cov(start_pose()));
  a.update(SE3::exp(vel * kDt) * start_pose(), measurement_cov(start_pose()));
  b = a;
  a.predict(0.1);
  b.predict(0.05);
  b.predict(0.05);
  EXPECT_LT(error(a.pose(), b.pose()).norm(), 1e-12);
  EXPECT_LT((a.covariance() - b.covariance()).norm(), 1e-3 * a.covariance().norm());
}

TEST(PoseFilter, NeverAllocates) {
  std::mt19937 rng(7);
  PoseFilter f;
  SE3 T = start_pose();
  Vector6d vel;
  vel << 0.1, 0.0, 0.05, 0.2, -0.1, 0.3;
  const Measurement z0 = measure(rng, T);
  const long before = g_allocations.load();
  f.reset(z0.T, z0.cov);
  double sum = 0.0;
  for (int k = 0; k < 30; ++k) {
    T = SE3::exp(vel * kDt) * T;
    f.predict(kDt);
    sum += f.predict_pose(kDt).translation().x();
    const Measurement z = measure(rng, T);
    sum += f.innovation_chi2(z.T, z.cov);
    sum += f.update(z.T, z.cov, 100.0);
    f.reset_velocity();
  }
  EXPECT_EQ(g_allocations.load() - before, 0);
  EXPECT_TRUE(std::isfinite(sum));
}

// Adaptive process noise: at rest the measurements' noise is averaged away; a motion restores
// the full noise in the very update that shows it.
TEST(PoseFilter, AdaptiveNoiseHoldsARestingObjectStillAndFollowsAJumpAtOnce) {
  PoseFilterParams p;
  p.adapt_noise = true;
  p.motion_chi2 = 22.5;  // 99.9 % of consistent measurements stay below
  PoseFilter f(p), plain(PoseFilterParams{});
  const SE3 truth(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, 0.5));
  Matrix6d R = Matrix6d::Zero();
  R.diagonal() << 1e-8, 1e-8, 4e-8, 1e-6, 1e-6, 1e-6;  // 0.1 / 0.2 mm, 0.06 deg
  f.reset(truth, R);
  plain.reset(truth, R);
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  double se = 0.0, se_plain = 0.0;
  int n = 0;
  for (int k = 0; k < 120; ++k) {
    const SE3 meas = noisy_measurement(truth, R, rng, g);
    f.predict(1.0 / 30.0);
    plain.predict(1.0 / 30.0);
    f.update(meas, R);
    plain.update(meas, R);
    if (k >= 20) {
      se += (f.pose().translation() - truth.translation()).squaredNorm();
      se_plain += (plain.pose().translation() - truth.translation()).squaredNorm();
      ++n;
    }
  }
  EXPECT_LE(f.noise_scale(), 1e-4);
  EXPECT_DOUBLE_EQ(plain.noise_scale(), 1.0);
  // The plain filter follows the noise, the adaptive one averages it.
  EXPECT_LT(std::sqrt(se / n), 0.5 * std::sqrt(se_plain / n));
  // A jump of 5 mm: taken at once (most of it), and the noise is back at full scale.
  const SE3 moved(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.005, 0.0, 0.5));
  f.predict(1.0 / 30.0);
  f.update(moved, R);
  EXPECT_DOUBLE_EQ(f.noise_scale(), 1.0);
  EXPECT_GT(f.pose().translation().x(), 0.004);
}

// velocity_chi2() is small at rest and large for a steady motion the filter has measured;
// hold_still() makes an adaptive filter at rest average the measurements (the pose is not the
// end of a line fitted through them) and never allocates.
TEST(PoseFilter, VelocityChi2AndHoldStill) {
  PoseFilterParams p;
  p.adapt_noise = true;
  PoseFilter full(PoseFilterParams{}), held(p), free(p);
  const SE3 truth(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, 0.5));
  Matrix6d R = Matrix6d::Zero();
  R.diagonal() << 1e-8, 1e-8, 4e-8, 1e-6, 1e-6, 1e-6;  // 0.1 / 0.2 mm, 0.06 deg
  for (PoseFilter* f : {&full, &held, &free}) f->reset(truth, R);
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  double se_held = 0.0, se_free = 0.0;
  int n = 0, quiet = 0;
  for (int k = 0; k < 60; ++k) {
    const SE3 meas = noisy_measurement(truth, R, rng, g);
    for (PoseFilter* f : {&full, &held, &free}) f->predict(1.0 / 30.0);
    full.update(meas, R);
    if (full.velocity_chi2() <= 4.0) ++quiet;  // at rest, the velocity is insignificant
    held.hold_still(1e-4, 1e-3);
    held.update(meas, R);
    free.update(meas, R);
    if (k >= 10) {
      se_held += (held.pose().translation() - truth.translation()).squaredNorm();
      se_free += (free.pose().translation() - truth.translation()).squaredNorm();
      ++n;
    }
  }
  EXPECT_GE(quiet, 57);  // of 60 frames
  EXPECT_LT(std::sqrt(se_held / n), 0.9 * std::sqrt(se_free / n));  // 0.46 vs 0.55 mm
  held.hold_still(1e-4, 1e-3);
  EXPECT_EQ(held.velocity(), Vector6d::Zero());
  EXPECT_DOUBLE_EQ(held.covariance()(6, 6), 1e-8);
  EXPECT_DOUBLE_EQ(held.covariance()(9, 9), 1e-6);
  EXPECT_TRUE((held.covariance().topRightCorner<6, 6>().isZero()));
  // A steady motion of 1 cm per frame: the velocity becomes significant.
  SE3 T = truth;
  for (int k = 0; k < 10; ++k) {
    T = SE3(Eigen::Quaterniond::Identity(), T.translation() + Eigen::Vector3d(0.01, 0.0, 0.0));
    full.predict(1.0 / 30.0);
    full.update(T, R);
  }
  EXPECT_GT(full.velocity_chi2(), 20.0);  // (54: far above a resting object's)
  // Before initialisation: nothing to test, nothing changed.
  PoseFilter none;
  EXPECT_EQ(none.velocity_chi2(), PoseFilter::kInvalidChi2);
  none.hold_still(1e-4, 1e-3);
  EXPECT_FALSE(none.initialised());
}
