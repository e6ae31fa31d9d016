// Kalibr camchain / imu.yaml reading, and EuRoC folders opened with them (TUM-VI style) or with missing
// images.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "io_test_util.h"
#include "linnet/core/error.h"
#include "linnet/io/euroc_dataset.h"
#include "linnet/io/kalibr_yaml.h"
#include "support/shared_data.h"

namespace linnet {
namespace {

namespace fs = std::filesystem;

/// A 4x4 transform as Kalibr writes it: a list of four rows.
std::string kalibrMatrix(const Pose& T, const std::string& indent) {
  const Mat4 M = T.matrix();
  std::string s;
  char buf[160];
  for (int r = 0; r < 4; ++r) {
    std::snprintf(buf, sizeof buf, "%s- [%.17g, %.17g, %.17g, %.17g]\n", indent.c_str(), M(r, 0), M(r, 1),
                  M(r, 2), M(r, 3));
    s += buf;
  }
  return s;
}

std::string camEntry(const std::string& name, const CameraCalibration& c, const std::string& extrinsics,
                     double timeshift) {
  char buf[2048];
  std::snprintf(buf, sizeof buf,
                "%s:\n%s  camera_model: pinhole\n  distortion_coeffs: [%.17g, %.17g, %.17g, %.17g]\n"
                "  distortion_model: radtan\n  intrinsics: [%.17g, %.17g, %.17g, %.17g]\n"
                "  resolution: [%d, %d]\n  rostopic: /%s/image_raw\n  timeshift_cam_imu: %.17g\n",
                name.c_str(), extrinsics.c_str(), c.distortion_coeffs[0], c.distortion_coeffs[1],
                c.distortion_coeffs[2], c.distortion_coeffs[3], c.intrinsics[0], c.intrinsics[1],
                c.intrinsics[2], c.intrinsics[3], c.width, c.height, name.c_str(), timeshift);
  return buf;
}

/// The EuRoC calibration as a Kalibr camchain (cam1 through T_cn_cnm1 when `chained`).
std::string eurocCamchain(const CameraCalibration& c0, const CameraCalibration& c1, bool chained,
                          double timeshift) {
  std::string text =
      camEntry("cam0", c0, "  T_cam_imu:\n" + kalibrMatrix(c0.T_B_C.inverse(), "  "), timeshift);
  const std::string ext1 = chained ? "  T_cn_cnm1:\n" + kalibrMatrix(c1.T_B_C.inverse() * c0.T_B_C, "  ")
                                   : "  T_cam_imu:\n" + kalibrMatrix(c1.T_B_C.inverse(), "  ");
  return text + camEntry("cam1", c1, ext1, timeshift);
}

void expectSamePose(const Pose& a, const Pose& b) {
  EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), 1e-12) << a.matrix() << "\n" << b.matrix();
}

TEST(KalibrYaml, CamchainMatchesTheEurocSensorYaml) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const fs::path mav0 = testing::eurocMicroDir() / "mav0";
  const CameraCalibration c0 = readCameraSensorYaml((mav0 / "cam0" / "sensor.yaml").string());
  const CameraCalibration c1 = readCameraSensorYaml((mav0 / "cam1" / "sensor.yaml").string());
  const io_test::TempDir dir("camchain");
  for (bool chained : {false, true}) {
    std::ofstream(dir / "camchain.yaml") << eurocCamchain(c0, c1, chained, 0.0);
    const KalibrCamchain chain = readKalibrCamchain((dir / "camchain.yaml").string());
    ASSERT_EQ(chain.cameras.size(), 2u);
    for (int i = 0; i < 2; ++i) {
      const CameraCalibration& ref = i == 0 ? c0 : c1;
      const CameraCalibration& got = chain.cameras[static_cast<std::size_t>(i)];
      EXPECT_EQ(got.intrinsics, ref.intrinsics);
      EXPECT_EQ(got.distortion_coeffs, ref.distortion_coeffs);
      EXPECT_EQ(got.distortion, "radtan");
      EXPECT_EQ(got.width, 752);
      expectSamePose(got.T_B_C, ref.T_B_C);
    }
    EXPECT_EQ(chain.timeshift_cam_imu_s[1], 0.0);
  }
}

TEST(KalibrYaml, ImuYamlNestedAndFlat) {
  const io_test::TempDir dir("imu");
  std::ofstream(dir / "imu.yaml")
      << "imu0:\n  T_i_b:\n  - [1, 0, 0, 0.5]\n  - [0, 1, 0, 0]\n  - [0, 0, 1, 0]\n"
         "  - [0, 0, 0, 1]\n  accelerometer_noise_density: 0.0028\n"
         "  accelerometer_random_walk: 0.00086\n  gyroscope_noise_density: 0.00016\n"
         "  gyroscope_random_walk: 2.2e-05\n  rostopic: /imu0\n  update_rate: 200.0\n";
  Pose T_B_I;
  const ImuNoise n = readImuSensorYaml((dir / "imu.yaml").string(), &T_B_I);
  EXPECT_EQ(n.acc_noise_density, 0.0028);
  EXPECT_EQ(n.gyr_random_walk, 2.2e-05);
  EXPECT_EQ(n.rate_hz, 200.0);
  EXPECT_EQ(T_B_I.p, Vec3(-0.5, 0, 0));  // T_i_b maps body to IMU; T_B_I is its inverse

  std::ofstream(dir / "flat.yaml")
      << "accelerometer_noise_density: 0.0028\naccelerometer_random_walk: 0.00086\n"
         "gyroscope_noise_density: 0.00016\nupdate_rate: 100.0\n";
  try {
    readImuSensorYaml((dir / "flat.yaml").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "flat.yaml").string() + ": missing key 'gyroscope_random_walk'");
  }
}

TEST(KalibrYaml, CamchainErrorsNameKeyPaths) {
  const io_test::TempDir dir("camchain_errors");
  std::ofstream(dir / "a.yaml") << "cam0:\n  camera_model: pinhole\n  intrinsics: [1, 1, 0, 0]\n"
                                   "  resolution: [10, 10]\n  distortion_model: equidistant\n"
                                   "  distortion_coeffs: [0, 0, 0, 0]\n";
  try {
    readKalibrCamchain((dir / "a.yaml").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "a.yaml").string() + ":2: missing key 'cam0.T_cam_imu'");
  }
  std::ofstream(dir / "b.yaml") << "cam0:\n  camera_model: omni\n";
  try {
    readKalibrCamchain((dir / "b.yaml").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing key 'cam0.resolution'"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "c.yaml") << "cam0:\n  camera_model: pinhole\n  intrinsics: [1, 1, 0, 0]\n"
                                   "  resolution: [10, 10]\n  distortion_model: equidistant\n"
                                   "  distortion_coeffs: [0, 0, 0]\n";
  try {
    readKalibrCamchain((dir / "c.yaml").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "c.yaml").string() +
                                         ":6: key 'cam0.distortion_coeffs' must hold 4 values for "
                                         "'equidistant', got 3");
  }
  std::ofstream(dir / "d.yaml") << "camera_model: pinhole\n";
  EXPECT_THROW(readKalibrCamchain((dir / "d.yaml").string()), InputError);
  // radtan: 4 (k1 k2 p1 p2) or 5 (with k3) coefficients.
  std::ofstream(dir / "e.yaml") << "cam0:\n  camera_model: pinhole\n  intrinsics: [1, 1, 0, 0]\n"
                                   "  resolution: [10, 10]\n  distortion_model: radtan\n"
                                   "  distortion_coeffs: [0.1, -0.05, 0.001, 0.002, 0.01]\n"
                                   "  T_cam_imu: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n";
  EXPECT_EQ(readKalibrCamchain((dir / "e.yaml").string()).cameras.at(0).distortion_coeffs.size(), 5u);
  std::ofstream(dir / "f.yaml") << "cam0:\n  camera_model: pinhole\n  intrinsics: [1, 1, 0, 0]\n"
                                   "  resolution: [10, 10]\n  distortion_model: radtan\n"
                                   "  distortion_coeffs: [0.1, -0.05, 0.001]\n"
                                   "  T_cam_imu: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n";
  try {
    readKalibrCamchain((dir / "f.yaml").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "f.yaml").string() +
                                         ":6: key 'cam0.distortion_coeffs' must hold 4 or 5 values for "
                                         "'radtan', got 3");
  }
}

TEST(KalibrYaml, DatasetWithCamchainInsteadOfSensorYaml) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const fs::path mav0 = testing::eurocMicroDir() / "mav0";
  const CameraCalibration c0 = readCameraSensorYaml((mav0 / "cam0" / "sensor.yaml").string());
  const CameraCalibration c1 = readCameraSensorYaml((mav0 / "cam1" / "sensor.yaml").string());
  const io_test::TempDir root("kalibr_dataset");
  io_test::copyEurocSubset(root, 5, 199, 0, false);  // no camN/sensor.yaml: the camchain must be used
  std::ofstream(root / "camchain.yaml") << eurocCamchain(c0, c1, true, 0.002);
  EurocOpenOptions o;
  o.camchain = (root / "camchain.yaml").string();
  const EurocDataset d = EurocDataset::open(root.string(), o);
  ASSERT_EQ(d.frames().size(), 5u);
  EXPECT_EQ(d.frames()[0].t, 1403715273262142976 + 2'000'000);  // on the IMU clock
  EXPECT_NEAR(d.cam0().rate_hz, 20.0, 1e-3);                    // from the time stamps
  expectSamePose(d.cam1()->T_B_C, c1.T_B_C);
  ASSERT_EQ(d.warnings().size(), 1u);
  EXPECT_NE(d.warnings()[0].find("shifted by 2000000 ns"), std::string::npos) << d.warnings()[0];

  // A camchain with cam0 only: monocular, although the folder has cam1.
  std::ofstream(root / "mono.yaml") << camEntry(
      "cam0", c0, "  T_cam_imu:\n" + kalibrMatrix(c0.T_B_C.inverse(), "  "), 0.0);
  o.camchain = (root / "mono.yaml").string();
  const EurocDataset m = EurocDataset::open(root.string(), o);
  EXPECT_FALSE(m.stereo());
  EXPECT_EQ(m.frames()[0].t, 1403715273262142976);
  EXPECT_TRUE(m.frames()[0].right_path.empty());

  // Without the camchain the missing sensor.yaml is reported.
  try {
    EurocDataset::open(root.string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cam0/sensor.yaml: file not found"), std::string::npos) << e.what();
  }
}

TEST(KalibrYaml, MissingImagesCanBeDropped) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const io_test::TempDir root("kalibr_drop");
  io_test::copyEurocSubset(root, 5, 199, 0, true);
  fs::remove(root / "mav0" / "cam1" / "data" / "1403715273462142976.png");
  EXPECT_THROW(EurocDataset::open(root.string()), InputError);
  EurocOpenOptions o;
  o.drop_missing_images = true;
  const EurocDataset d = EurocDataset::open(root.string(), o);
  EXPECT_EQ(d.frames().size(), 4u);
  ASSERT_EQ(d.warnings().size(), 2u);
  EXPECT_EQ(d.warnings()[0], "cam1: dropped 1 rows whose image file is missing");
  EXPECT_NE(d.warnings()[1].find("dropped 1 frames without a partner"), std::string::npos);
}

}  // namespace
}  // namespace linnet
