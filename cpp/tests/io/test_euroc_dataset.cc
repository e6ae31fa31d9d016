// EuRoC ASL reader: the real V1_01_easy micro set, and broken copies of a few of its frames in a temp folder.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "io_test_util.h"
#include "linnet/core/error.h"
#include "linnet/io/euroc_dataset.h"
#include "linnet/io/text_parse.h"
#include "support/shared_data.h"

namespace linnet {
namespace {

namespace fs = std::filesystem;

constexpr Timestamp kFirst = 1403715273262142976;
constexpr Timestamp kLast = 1403715277962142976;

std::string readAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
void writeAll(const fs::path& p, const std::string& text) { io_test::writeFile(p, text); }

/// A small copy of the micro set (5 stereo frames, 300 IMU rows, 10 GT rows) in a fresh temp folder.
io_test::TempDir makeSmallCopy(const std::string& name) {
  io_test::TempDir root("euroc_" + name);
  io_test::copyEurocSubset(root, 5, 300, 10, true);
  return root;
}

/// The InputError message of opening `root`, or "" if it opens.
std::string openError(const fs::path& root) {
  try {
    EurocDataset::open(root.string());
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

void replaceInFile(const fs::path& p, const std::string& from, const std::string& to) {
  std::string text = readAll(p);
  const auto pos = text.find(from);
  ASSERT_NE(pos, std::string::npos) << from;
  text.replace(pos, from.size(), to);
  writeAll(p, text);
}

TEST(EurocDataset, ReadsTheRealMicroSequence) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const EurocDataset d = EurocDataset::open(testing::eurocMicroDir().string());
  EXPECT_TRUE(d.warnings().empty()) << d.warnings().front();
  ASSERT_EQ(d.frames().size(), 95u);
  EXPECT_EQ(d.frames().front().t, kFirst);
  EXPECT_EQ(d.frames().back().t, kLast);
  EXPECT_NEAR(d.durationSeconds(), 4.7, 1e-9);
  EXPECT_TRUE(d.stereo());
  EXPECT_NE(d.frames()[3].left_path.find("cam0/data/1403715273412143104.png"), std::string::npos);
  EXPECT_NE(d.frames()[3].right_path.find("cam1/data/1403715273412143104.png"), std::string::npos);

  // cam0 / cam1 calibration (sensor.yaml).
  const CameraCalibration& c0 = d.cam0();
  EXPECT_EQ(c0.model, "pinhole");
  EXPECT_EQ(c0.distortion, "radtan");
  EXPECT_EQ(c0.width, 752);
  EXPECT_EQ(c0.height, 480);
  EXPECT_EQ(c0.intrinsics[0], 458.654);
  EXPECT_EQ(c0.intrinsics[1], 457.296);
  EXPECT_EQ(c0.intrinsics[2], 367.215);
  EXPECT_EQ(c0.intrinsics[3], 248.375);
  ASSERT_EQ(c0.distortion_coeffs.size(), 4u);
  EXPECT_EQ(c0.distortion_coeffs[0], -0.28340811);
  EXPECT_EQ(c0.distortion_coeffs[3], 1.76187114e-05);
  EXPECT_EQ(c0.rate_hz, 20.0);
  const Mat4 T0 = c0.T_B_C.matrix();
  EXPECT_NEAR(T0(0, 1), -0.999880929698, 1e-9);
  EXPECT_NEAR(T0(1, 0), 0.999557249008, 1e-9);
  EXPECT_EQ(c0.T_B_C.p, Vec3(-0.0216401454975, -0.064676986768, 0.00981073058949));
  ASSERT_NE(d.cam1(), nullptr);
  EXPECT_EQ(d.cam1()->intrinsics[0], 457.587);
  EXPECT_EQ(d.cam1()->T_B_C.p, Vec3(-0.0198435579556, 0.0453689425024, 0.00786212447038));
  // The stereo baseline of EuRoC: about 11 cm.
  EXPECT_NEAR((c0.T_B_C.inverse() * d.cam1()->T_B_C).p.norm(), 0.110, 0.001);
  EXPECT_EQ(d.rig().cameras.size(), 2u);

  // IMU: the whole 145.6 s log, gyro columns first.
  const ImuNoise& n = d.imuNoise();
  EXPECT_EQ(n.gyr_noise_density, 1.6968e-04);
  EXPECT_EQ(n.gyr_random_walk, 1.9393e-05);
  EXPECT_EQ(n.acc_noise_density, 2.0e-3);
  EXPECT_EQ(n.acc_random_walk, 3.0e-3);
  EXPECT_EQ(n.rate_hz, 200.0);
  ASSERT_EQ(d.imu().size(), 29120u);
  EXPECT_EQ(d.imu().front().t, kFirst);
  EXPECT_EQ(d.imu().back().t, 1403715418857143040);
  EXPECT_EQ(d.imu().front().gyr, Vec3(-0.0020943951023931952, 0.017453292519943295, 0.07749261878854824));
  EXPECT_EQ(d.imu().front().acc, Vec3(9.0874956666666655, 0.13075533333333333, -3.6938381666666662));
  const auto [i0, i1] = d.imuRange(kFirst, kLast);
  EXPECT_EQ(i0, 0u);
  EXPECT_EQ(i1 - i0, 941u);

  // Ground truth: 17 columns at 20 Hz for the whole sequence.
  ASSERT_EQ(d.groundTruth().size(), 2895u);
  const GroundTruthState& g = d.groundTruth().front();
  EXPECT_EQ(g.t, kFirst);
  EXPECT_TRUE(g.has_velocity_bias);
  EXPECT_EQ(g.T_W_B.p, Vec3(0.878895, 2.1834, 0.948427));
  EXPECT_NEAR(g.T_W_B.q.w(), 0.069433, 1e-5);
  EXPECT_NEAR(g.T_W_B.q.x(), -0.824237, 1e-5);
  EXPECT_EQ(g.v_W, Vec3(0.00157587, 0.00179383, -0.00231615));
  EXPECT_EQ(g.b_g, Vec3(-0.00224703, 0.0215352, 0.0770299));
  EXPECT_EQ(g.b_a, Vec3(-0.0180115, 0.0659796, 0.0309774));
  EXPECT_EQ(d.groundTruth().back().t, 1403715417962142976);

  GroundTruthState mid;
  ASSERT_TRUE(d.groundTruthAt(kFirst + (d.groundTruth()[1].t - kFirst) / 2, &mid));  // exactly half way
  EXPECT_NEAR((mid.T_W_B.p - 0.5 * (g.T_W_B.p + d.groundTruth()[1].T_W_B.p)).norm(), 0.0, 1e-12);
  EXPECT_FALSE(d.groundTruthAt(kFirst - 1, &mid));

  // The images: 752x480 8-bit gray.
  const cv::Mat img = EurocDataset::loadImage(d.frames()[0].left_path);
  EXPECT_EQ(img.cols, 752);
  EXPECT_EQ(img.rows, 480);
  EXPECT_EQ(img.type(), CV_8UC1);
}

TEST(EurocDataset, OpensTheMav0FolderItselfAndMono) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const EurocDataset d = EurocDataset::open((testing::eurocMicroDir() / "mav0").string());
  EXPECT_EQ(d.frames().size(), 95u);
  EurocOpenOptions mono;
  mono.use_cam1 = false;
  mono.load_ground_truth = false;
  const EurocDataset m = EurocDataset::open(testing::eurocMicroDir().string(), mono);
  EXPECT_FALSE(m.stereo());
  EXPECT_EQ(m.cam1(), nullptr);
  EXPECT_TRUE(m.frames()[0].right_path.empty());
  EXPECT_TRUE(m.groundTruth().empty());
}

TEST(EurocDataset, SmallCopyOpensWithCrlfAndNoGroundTruth) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const auto root = makeSmallCopy("crlf");
  for (const char* f : {"cam0/data.csv", "imu0/data.csv"}) {
    std::string text = readAll(root / "mav0" / f), crlf;
    for (char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
    writeAll(root / "mav0" / f, crlf);
  }
  fs::remove_all(root / "mav0" / "state_groundtruth_estimate0");
  const EurocDataset d = EurocDataset::open(root.string());
  EXPECT_EQ(d.frames().size(), 5u);
  EXPECT_EQ(d.imu().size(), 300u);
  EXPECT_TRUE(d.groundTruth().empty());
  EXPECT_TRUE(fs::exists(d.frames()[4].left_path));
  EXPECT_EQ(d.imu()[299].acc.z(), d.imu()[299].acc.z());  // parsed, not NaN
}

TEST(EurocDataset, UnpairedFramesAreDroppedAndReported) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const auto root = makeSmallCopy("unpaired");
  const fs::path csv = root / "mav0" / "cam1" / "data.csv";
  replaceInFile(csv, "1403715273312143104,1403715273312143104.png\n", "");
  const EurocDataset d = EurocDataset::open(root.string());
  EXPECT_EQ(d.frames().size(), 4u);
  ASSERT_EQ(d.warnings().size(), 1u);
  EXPECT_NE(d.warnings()[0].find("dropped 1 frames"), std::string::npos) << d.warnings()[0];
  EXPECT_NE(d.warnings()[0].find("cam0 1, cam1 0"), std::string::npos) << d.warnings()[0];
}

TEST(EurocDataset, MissingImageNamesCsvLineAndFile) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const auto root = makeSmallCopy("missing_image");
  fs::remove(root / "mav0" / "cam1" / "data" / "1403715273362142976.png");
  const std::string msg = openError(root);
  EXPECT_NE(msg.find("cam1/data.csv:4: image not found on disk"), std::string::npos) << msg;
  EXPECT_NE(msg.find("1403715273362142976.png"), std::string::npos) << msg;
}

TEST(EurocDataset, TruncatedCsvLineNamesFileAndLine) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const auto root = makeSmallCopy("truncated");
  const fs::path csv = root / "mav0" / "imu0" / "data.csv";
  std::string text = readAll(csv);
  text.resize(text.rfind(',', text.size() - 40));  // cut the last row inside its 4th column
  writeAll(csv, text);
  const std::string msg = openError(root);
  EXPECT_NE(msg.find("imu0/data.csv:301: expected 7 columns"), std::string::npos) << msg;

  // A broken number: the column is named.
  const auto root2 = makeSmallCopy("bad_number");
  replaceInFile(root2 / "mav0" / "imu0" / "data.csv", "9.0874956666666655", "9.08x");
  const std::string msg2 = openError(root2);
  EXPECT_NE(msg2.find("imu0/data.csv:2: column 'a_RS_S_x': expected a number, got '9.08x'"),
            std::string::npos)
      << msg2;
}

TEST(EurocDataset, NonMonotonicAndDuplicatedTimeStamps) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const auto root = makeSmallCopy("backwards");
  replaceInFile(root / "mav0" / "cam0" / "data.csv", "1403715273362142976,", "1403715273212142976,");
  const std::string msg = openError(root);
  EXPECT_NE(msg.find("cam0/data.csv:4: time stamp 1403715273212142976 ns goes backwards"), std::string::npos)
      << msg;

  const auto root2 = makeSmallCopy("duplicate");
  replaceInFile(root2 / "mav0" / "imu0" / "data.csv", "1403715273267142912,", "1403715273262142976,");
  const std::string msg2 = openError(root2);
  EXPECT_NE(msg2.find("imu0/data.csv:3: time stamp 1403715273262142976 ns is duplicated"), std::string::npos)
      << msg2;

  const auto root3 = makeSmallCopy("gt_backwards");
  replaceInFile(root3 / "mav0" / "state_groundtruth_estimate0" / "data.csv", "1403715273312143104,",
                "1403715273112143104,");
  const std::string msg3 = openError(root3);
  EXPECT_NE(msg3.find("state_groundtruth_estimate0/data.csv:3: time stamp"), std::string::npos) << msg3;
}

TEST(EurocDataset, BadOrIncompleteSensorYaml) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const auto root = makeSmallCopy("bad_yaml");
  replaceInFile(root / "mav0" / "cam0" / "sensor.yaml", "resolution: [752, 480]", "resolution: [752, 480");
  const std::string msg = openError(root);
  EXPECT_NE(msg.find("cam0/sensor.yaml:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("YAML syntax error"), std::string::npos) << msg;

  const auto root2 = makeSmallCopy("incomplete_yaml");
  replaceInFile(root2 / "mav0" / "cam1" / "sensor.yaml", "intrinsics:", "intrinsic:");
  const std::string msg2 = openError(root2);
  EXPECT_NE(msg2.find("cam1/sensor.yaml: missing key 'intrinsics'"), std::string::npos) << msg2;

  const auto root3 = makeSmallCopy("bad_value_yaml");
  replaceInFile(root3 / "mav0" / "imu0" / "sensor.yaml", "gyroscope_random_walk: 1.9393e-05",
                "gyroscope_random_walk: fast");
  const std::string msg3 = openError(root3);
  EXPECT_NE(msg3.find("imu0/sensor.yaml:18: key 'gyroscope_random_walk' expects a number, got 'fast'"),
            std::string::npos)
      << msg3;

  const auto root4 = makeSmallCopy("bad_tbs");
  replaceInFile(root4 / "mav0" / "cam0" / "sensor.yaml", "0.0, 0.0, 0.0, 1.0]", "0.0, 0.0, 1.0]");
  const std::string msg4 = openError(root4);
  EXPECT_NE(msg4.find("cam0/sensor.yaml:8: key 'T_BS' has rows*cols = 16 but 15 data values"),
            std::string::npos)
      << msg4;

  const auto root5 = makeSmallCopy("bad_distortion");
  replaceInFile(root5 / "mav0" / "cam0" / "sensor.yaml", "radial-tangential", "fov");
  const std::string msg5 = openError(root5);
  EXPECT_NE(msg5.find("key 'distortion_model' = 'fov' is not supported"), std::string::npos) << msg5;
}

TEST(EurocDataset, MissingFilesAndFolders) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const auto root = makeSmallCopy("missing_sensor_yaml");
  fs::remove(root / "mav0" / "imu0" / "sensor.yaml");
  const std::string msg = openError(root);
  EXPECT_NE(msg.find("imu0/sensor.yaml: file not found"), std::string::npos) << msg;

  const auto root2 = makeSmallCopy("missing_csv");
  fs::remove(root2 / "mav0" / "cam0" / "data.csv");
  const std::string msg2 = openError(root2);
  EXPECT_NE(msg2.find("cam0/data.csv: file not found"), std::string::npos) << msg2;

  const auto root3 = makeSmallCopy("missing_mav0");
  fs::rename(root3 / "mav0", root3 / "mav1");
  const std::string msg3 = openError(root3);
  EXPECT_NE(msg3.find(root3.string() + ": no mav0/ folder"), std::string::npos) << msg3;

  EXPECT_NE(openError(root3.path() / "nowhere").find("nowhere: dataset folder not found"), std::string::npos);
}

TEST(EurocDataset, LoadImageErrorsNameTheFile) {
  const io_test::TempDir dir("images");
  try {
    EurocDataset::loadImage((dir / "absent.png").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("absent.png: image file not found"), std::string::npos) << e.what();
  }
  writeAll(dir / "corrupt.png", "\x89PNG\r\n\x1a\n this is not a png");
  try {
    EurocDataset::loadImage((dir / "corrupt.png").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("corrupt.png: cannot decode image"), std::string::npos) << e.what();
  }
  writeAll(dir / "empty.png", "");
  try {
    EurocDataset::loadImage((dir / "empty.png").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("empty.png: cannot decode image (empty file)"), std::string::npos)
        << e.what();
  }
  // A valid PNG cut in half (the file is read whole, then decoded from memory).
  cv::Mat img(48, 64, CV_8UC1);
  cv::randu(img, 0, 256);
  std::vector<unsigned char> png;
  ASSERT_TRUE(cv::imencode(".png", img, png));
  writeAll(dir / "whole.png", std::string(png.begin(), png.end()));
  const cv::Mat back = EurocDataset::loadImage((dir / "whole.png").string());
  EXPECT_EQ(cv::countNonZero(back != img), 0);
  writeAll(dir / "half.png", std::string(png.begin(), png.begin() + static_cast<std::ptrdiff_t>(png.size() / 2)));
  try {
    EurocDataset::loadImage((dir / "half.png").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("half.png: cannot decode image"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace linnet
