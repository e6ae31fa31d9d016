// TUM / EuRoC csv trajectories and PLY / OBJ maps: exact round trips, real files, line-numbered errors.
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "io_test_util.h"
#include "linnet/core/error.h"
#include "linnet/io/map_io.h"
#include "linnet/io/trajectory_io.h"
#include "support/shared_data.h"

namespace linnet {
namespace {

namespace fs = std::filesystem;

std::string readAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::vector<TrajectoryState> randomTrajectory(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<TrajectoryState> states;
  Timestamp t = 1403715273262142976;
  for (int i = 0; i < n; ++i) {
    TrajectoryState s;
    t += 50'000'000 + (i % 3);
    s.t = t;
    s.T_W_B = Pose(expSO3(Vec3(g(rng), g(rng), g(rng))), Vec3(g(rng), g(rng), g(rng)) * 10.0);
    s.v_W = Vec3(g(rng), g(rng), g(rng));
    s.b_g = Vec3(g(rng), g(rng), g(rng)) * 1e-3;
    s.b_a = Vec3(g(rng), g(rng), g(rng)) * 1e-2;
    s.has_velocity_bias = true;
    states.push_back(s);
  }
  return states;
}

std::string readError(const fs::path& p) {
  try {
    readTrajectory(p.string());
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(TrajectoryIo, TumRoundTripIsExact) {
  const io_test::TempDir dir("tum");
  const auto states = randomTrajectory(200, 1);
  const std::string path = (dir / "traj.tum").string();
  writeTum(path, states);
  const auto back = readTum(path);
  ASSERT_EQ(back.size(), states.size());
  for (std::size_t i = 0; i < states.size(); ++i) {
    EXPECT_EQ(back[i].t, states[i].t);
    EXPECT_EQ(back[i].T_W_B.p, states[i].T_W_B.p);
    EXPECT_EQ(back[i].T_W_B.q.coeffs(), states[i].T_W_B.q.coeffs());
    EXPECT_FALSE(back[i].has_velocity_bias);
  }
  // Seconds with exactly 9 decimals, TUM order x y z qx qy qz qw.
  TrajectoryState s;
  s.t = 1403715273262142976;
  s.T_W_B = Pose(Quat(0.5, 0.5, -0.5, 0.5), Vec3(1.25, -2.0, 0.1));
  EXPECT_EQ(formatTumLine(s), "1403715273.262142976 1.25 -2 0.1 0.5 -0.5 0.5 0.5");
}

TEST(TrajectoryIo, EurocCsvRoundTripIsExact) {
  const io_test::TempDir dir("csv");
  const auto states = randomTrajectory(200, 2);
  const std::string path = (dir / "traj.csv").string();
  writeTrajectory(path, states, trajectoryFormatFromPath(path));
  const std::string text = readAll(path);
  EXPECT_EQ(text.rfind("#timestamp [ns],p_RS_R_x [m]", 0), 0u);
  const auto back = readTrajectory(path);
  ASSERT_EQ(back.size(), states.size());
  for (std::size_t i = 0; i < states.size(); ++i) {
    EXPECT_EQ(back[i].t, states[i].t);
    EXPECT_EQ(back[i].T_W_B.p, states[i].T_W_B.p);
    EXPECT_EQ(back[i].T_W_B.q.coeffs(), states[i].T_W_B.q.coeffs());
    EXPECT_EQ(back[i].v_W, states[i].v_W);
    EXPECT_EQ(back[i].b_g, states[i].b_g);
    EXPECT_EQ(back[i].b_a, states[i].b_a);
    EXPECT_TRUE(back[i].has_velocity_bias);
  }
  // EuRoC order: w x y z after the position, then v, b_w, b_a.
  TrajectoryState s;
  s.t = 7;
  s.T_W_B = Pose(Quat(0.5, 0.5, -0.5, 0.5), Vec3(1, 2, 3));
  s.v_W = Vec3(4, 5, 6);
  s.b_g = Vec3(7, 8, 9);
  s.b_a = Vec3(10, 11, 12);
  EXPECT_EQ(formatEurocCsvLine(s), "7,1,2,3,0.5,0.5,-0.5,0.5,4,5,6,7,8,9,10,11,12");
}

TEST(TrajectoryIo, StreamingWriterMatchesWholeFileWriter) {
  const io_test::TempDir dir("stream");
  const auto states = randomTrajectory(50, 3);
  for (auto format : {TrajectoryFormat::kTum, TrajectoryFormat::kEurocCsv}) {
    const std::string a = (dir / "a.txt").string(), b = (dir / "b.txt").string();
    writeTrajectory(a, states, format);
    {
      TrajectoryFileWriter w(b, format);
      for (const auto& s : states) w.write(s);
      w.close();
      EXPECT_THROW(w.write(states[0]), UsageError);
    }
    EXPECT_EQ(readAll(a), readAll(b));
  }
}

TEST(TrajectoryIo, ReadsTheSharedGroundTruthFiles) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const auto official =
      readTum((testing::eurocMicroDir() / "extras" / "V1_01_easy_original_gt_200hz_tum.txt").string());
  EXPECT_EQ(official.size(), 28712u);
  EXPECT_EQ(official.front().t / 1'000'000, 1403715274302);  // starts 1.04 s after the first image
  const auto v2g_tum =
      readTum((testing::eurocMicroDir() / "extras" / "V1_01_easy_vicon2gt_20hz_tum.txt").string());
  const auto v2g_csv =
      readEurocCsv((testing::eurocMicroDir() / "mav0" / "state_groundtruth_estimate0" / "data.csv").string());
  ASSERT_EQ(v2g_tum.size(), v2g_csv.size());
  for (std::size_t i = 0; i < v2g_tum.size(); i += 97) {
    EXPECT_LE(std::abs(v2g_tum[i].t - v2g_csv[i].t), 10'000);  // the TUM file has 5 decimals (10 us)
    EXPECT_NEAR((v2g_tum[i].T_W_B.p - v2g_csv[i].T_W_B.p).norm(), 0.0, 1e-6);
    EXPECT_NEAR(v2g_tum[i].T_W_B.q.angularDistance(v2g_csv[i].T_W_B.q), 0.0, 1e-5);
  }
  // Reading with one thread or many gives the same states.
  const auto one =
      readTum((testing::eurocMicroDir() / "extras" / "V1_01_easy_original_gt_200hz_tum.txt").string(), 1);
  ASSERT_EQ(one.size(), official.size());
  for (std::size_t i = 0; i < one.size(); ++i) ASSERT_EQ(one[i].T_W_B.p, official[i].T_W_B.p);
}

TEST(TrajectoryIo, ErrorsNameFileAndLine) {
  const io_test::TempDir dir("traj_errors");
  const auto write = [&](const char* name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return dir / name;
  };
  EXPECT_EQ(readError(write("cols.tum", "# c\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n")),
            (dir / "cols.tum").string() + ":3: expected 8 columns 't x y z qx qy qz qw', got 7");
  EXPECT_EQ(readError(write("num.tum", "1.0 0 0 0 0 0 0 1\n2.0 0 y 0 0 0 0 1\n")),
            (dir / "num.tum").string() + ":2: column 'ty': expected a number, got 'y'");
  EXPECT_EQ(readError(write("time.tum", "1.0 0 0 0 0 0 0 1\n\n0.5 0 0 0 0 0 0 1\n")),
            (dir / "time.tum").string() +
                ":3: time stamp 500000000 ns goes backwards (previous row 1000000000 ns)");
  EXPECT_EQ(readError(write("quat.tum", "1.0 0 0 0 0 0 0 0\n")),
            (dir / "quat.tum").string() + ":1: quaternion has zero norm or is not finite");
  EXPECT_EQ(readError(write("c.csv", "#h\n1,0,0,0,1,0,0,0\n2,0,0,0,1,0,0,0,1\n")),
            (dir / "c.csv").string() + ":3: expected 8 columns like the first row, got 9");
  EXPECT_EQ(readError(write("d.csv", "1,0,0,0,1,0,0,0\r\n1,0,0,0,1,0,0,0\r\n")),
            (dir / "d.csv").string() + ":2: time stamp 1 ns is duplicated (previous row 1 ns)");
  EXPECT_EQ(
      readError(write("e.csv", "1,0,0\n")),
      (dir / "e.csv").string() + ":1: expected 17 (t, p, q, v, b_w, b_a) or 8 (t, p, q) columns, got 3");
  EXPECT_EQ(readError(dir / "absent.csv"), (dir / "absent.csv").string() + ": file not found");
  // Unnormalised quaternions written with few digits are normalised.
  const auto q = readTum(write("q.tum", "1.0 0 0 0 0 0 0 2\n").string());
  EXPECT_EQ(q[0].T_W_B.q.w(), 1.0);
}

TEST(MapIo, PlyRoundTripWithPointsSegmentsAndColours) {
  const io_test::TempDir dir("ply");
  MapGeometry map;
  map.points = {Vec3(0.1, 0.2, 0.3), Vec3(-1e-9, 5.5, 1e6), Vec3(1.0 / 3.0, 0, 0)};
  map.point_colors = {{255, 0, 0}, {0, 255, 0}, {1, 2, 3}};
  map.segments = {{Vec3(0, 0, 0), Vec3(1, 0, 0)}, {Vec3(0, 1, 2), Vec3(0.5, 0.25, 0.125)}};
  map.segment_colors = {{9, 9, 9}, {10, 20, 30}};
  const std::string path = (dir / "map.ply").string();
  writeMap(path, map);
  const std::string text = readAll(path);
  EXPECT_NE(text.find("element vertex 7\n"), std::string::npos) << text;
  EXPECT_NE(text.find("element edge 2\nproperty int vertex1\nproperty int vertex2\n"), std::string::npos)
      << text;
  EXPECT_NE(text.find("\n3 4\n5 6\n"), std::string::npos) << text;
  const MapGeometry back = readPly(path);
  ASSERT_EQ(back.points.size(), 3u);
  ASSERT_EQ(back.segments.size(), 2u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(back.points[i], map.points[i]);
    EXPECT_EQ(back.point_colors[i], map.point_colors[i]);
  }
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(back.segments[i].a, map.segments[i].a);
    EXPECT_EQ(back.segments[i].b, map.segments[i].b);
    EXPECT_EQ(back.segment_colors[i], map.segment_colors[i]);
  }
  // Points only, no colours: a plain x y z cloud.
  MapGeometry plain;
  plain.points = {Vec3(1, 2, 3)};
  writePly(path, plain);
  EXPECT_EQ(readAll(path).find("red"), std::string::npos);
  EXPECT_EQ(readPly(path).points[0], Vec3(1, 2, 3));
}

TEST(MapIo, ObjAndErrors) {
  const io_test::TempDir dir("obj");
  MapGeometry map;
  map.points = {Vec3(1, 2, 3)};
  map.segments = {{Vec3(0, 0, 0), Vec3(1, 1, 1)}};
  writeMap((dir / "m.obj").string(), map);
  EXPECT_EQ(readAll(dir / "m.obj"),
            "# Linnet point-and-line map (world frame, metres)\nv 1 2 3\nv 0 0 0\nv 1 1 1\nl 2 3\n");
  map.point_colors = {{1, 2, 3}, {4, 5, 6}};
  EXPECT_THROW(writePly((dir / "x.ply").string(), map), UsageError);
  EXPECT_THROW(writePly((dir / "no_dir" / "x.ply").string(), MapGeometry{}), InputError);

  std::ofstream(dir / "bad.ply")
      << "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
         "property float z\nend_header\n1 2 3\n4 5\n";
  try {
    readPly((dir / "bad.ply").string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              (dir / "bad.ply").string() + ":9: element 'vertex' row has 2 values, expected 3");
  }
  std::ofstream(dir / "bin.ply") << "ply\nformat binary_little_endian 1.0\nend_header\n";
  EXPECT_THROW(readPly((dir / "bin.ply").string()), InputError);
}

}  // namespace
}  // namespace linnet
