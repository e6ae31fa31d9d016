// Reader of the EuRoC ASL dataset layout (Burri et al., "The EuRoC micro aerial vehicle datasets",
// IJRR 2016). Under <root>/mav0/:
//   cam0/data.csv      "#timestamp [ns],filename"; the images are cam0/data/<filename>
//   cam0/sensor.yaml   Kalibr style: T_BS {rows, cols, data}, rate_hz, resolution [w, h], camera_model,
//                      intrinsics [fx fy cx cy], distortion_model, distortion_coefficients
//   cam1/...           optional (mono without it)
//   imu0/data.csv      "#timestamp [ns],w_x,w_y,w_z [rad/s],a_x,a_y,a_z [m/s^2]" (gyro first)
//   imu0/sensor.yaml   gyroscope/accelerometer noise densities and random walks, rate_hz, T_BS
//   state_groundtruth_estimate0/data.csv   optional; 17 columns (t, p, q_wxyz, v, b_w, b_a) or 8 (t, p, q)
//
// Body frame B = IMU frame (DESIGN A3). If imu0's T_BS is not the identity the camera extrinsics are
// re-expressed in the IMU frame (T_I_C = T_B_I^-1 T_B_C) and a warning is recorded.
// open() parses every csv (std::from_chars, no iostreams) and checks that every listed image exists (one
// directory listing per camera, no image is decoded). Every problem is an InputError naming the file, and
// the line for csv rows.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/pose.h"
#include "linnet/core/types.h"
#include "linnet/imu/imu_types.h"
#include "linnet/io/kalibr_yaml.h"
#include "linnet/io/trajectory_io.h"

namespace linnet {

/// One image time stamp with the paths of its image files.
struct StereoFrameRef {
  Timestamp t = 0;         // ns
  std::string left_path;   // cam0 image
  std::string right_path;  // cam1 image; empty for a monocular dataset
};

/// A ground-truth row (state_groundtruth_estimate0): pose of the body in the world, and velocity and biases
/// when the file has 17 columns (has_velocity_bias).
using GroundTruthState = TrajectoryState;

struct EurocOpenOptions {
  bool use_cam1 = true;              // read cam1 when present (false: monocular)
  bool check_images = true;          // every listed image must exist on disk
  bool drop_missing_images = false;  // drop rows whose image is missing (warning) instead of failing
  bool load_ground_truth = true;     // read state_groundtruth_estimate0 when present
  int threads = 0;                   // csv parsing threads (0: all cores); same result for any count
  std::string camchain;  // Kalibr camchain.yaml to use instead of camN/sensor.yaml ("": sensor.yaml)
  std::string imu_yaml;  // Kalibr imu.yaml to use instead of imu0/sensor.yaml ("": sensor.yaml)
  bool read_calibration = true;  // false: no sensor.yaml is read (the calibration comes from elsewhere, e.g. a
                                 // config file): cam0() / cam1() / imuNoise() are defaults

  template <class V>
  void visit(V& v) {
    v("use_cam1", use_cam1, "read cam1 when present (false: monocular)");
    v("check_images", check_images, "every image listed in data.csv must exist");
    v("drop_missing_images", drop_missing_images, "drop rows whose image is missing instead of failing");
    v("load_ground_truth", load_ground_truth, "read state_groundtruth_estimate0 when present");
    v("threads", threads, "csv parsing threads (0: all cores)", 0, 64);
    v("camchain", camchain, "Kalibr camchain.yaml instead of camN/sensor.yaml (empty: sensor.yaml)");
    v("imu_yaml", imu_yaml, "Kalibr imu.yaml instead of imu0/sensor.yaml (empty: sensor.yaml)");
    v("read_calibration", read_calibration, "read the sensor.yaml files (false: calibration from elsewhere)");
  }
};

class EurocDataset {
 public:
  /// `path` is the folder holding mav0/, or mav0 itself. Throws InputError (see the top of this file).
  static EurocDataset open(const std::string& path, const EurocOpenOptions& options = {});

  const std::string& root() const { return mav0_; }  // the mav0 folder
  const CameraCalibration& cam0() const { return cam0_; }
  const CameraCalibration* cam1() const { return has_cam1_ ? &cam1_ : nullptr; }
  CameraRig rig() const;  // cam0 (+ cam1)
  const ImuNoise& imuNoise() const { return imu_noise_; }
  const std::vector<ImuSample>& imu() const { return imu_; }
  const std::vector<StereoFrameRef>& frames() const { return frames_; }  // sorted, paired by exact time stamp
  const std::vector<GroundTruthState>& groundTruth() const { return ground_truth_; }  // empty if absent
  bool stereo() const { return has_cam1_; }
  /// Span of the image stream (first to last frame), seconds; 0 with fewer than two frames.
  double durationSeconds() const;
  /// Things that were accepted but worth knowing (unpaired frames dropped, non-identity imu0 T_BS, ...).
  const std::vector<std::string>& warnings() const { return warnings_; }

  /// Index range [first, last) of the IMU samples with t0 <= t <= t1 (binary search).
  std::pair<std::size_t, std::size_t> imuRange(Timestamp t0, Timestamp t1) const;
  /// Ground truth at `t`: linear interpolation of position, velocity and biases, slerp of the rotation,
  /// between the two rows around t. False if t is outside the ground truth or the rows are more than
  /// max_gap_ns apart.
  bool groundTruthAt(Timestamp t, GroundTruthState* state, Timestamp max_gap_ns = 100'000'000) const;

  /// Reads an image as 8-bit gray. InputError naming the file if it is missing or cannot be decoded.
  static cv::Mat loadImage(const std::string& path);

 private:
  std::string mav0_;
  CameraCalibration cam0_, cam1_;
  bool has_cam1_ = false;
  ImuNoise imu_noise_;
  std::vector<ImuSample> imu_;
  std::vector<StereoFrameRef> frames_;
  std::vector<GroundTruthState> ground_truth_;
  std::vector<std::string> warnings_;
};

/// A EuRoC camera data.csv: (time stamp, file name) rows, strictly increasing in time.
struct CameraCsvRow {
  Timestamp t = 0;
  std::string filename;
  long line = 0;  // line in the csv (for messages)
};
std::vector<CameraCsvRow> readCameraCsv(const std::string& path, int max_threads = 0);

/// A EuRoC imu0 data.csv (7 columns, gyro first), strictly increasing in time.
std::vector<ImuSample> readImuCsv(const std::string& path, int max_threads = 0);

}  // namespace linnet
