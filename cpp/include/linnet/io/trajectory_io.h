// Trajectory files: TUM and EuRoC-style csv, writers and readers.
//
// TUM (Sturm et al., IROS 2012): one pose per line, "t x y z qx qy qz qw"; t in seconds, written with
//   exactly 9 decimals (the int64 ns stamp printed without rounding); position of B in W in metres;
//   quaternion q_W_B in TUM order x y z w (Hamilton). Lines starting with '#' are comments.
// EuRoC csv (ASL state_groundtruth_estimate0/data.csv): 17 columns
//   t_ns, p xyz, q wxyz (EuRoC order), v_W xyz (m/s), gyro bias xyz (rad/s), accel bias xyz (m/s^2).
//   The 8-column variant (t, p, q) is read too.
// Numbers are written with the shortest text that parses back to the same double: write -> read is exact.
#pragma once

#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"

namespace linnet {

/// One time-stamped navigation state: the rows of a ground-truth file or an estimator's output.
struct TrajectoryState {
  Timestamp t = 0;                 // ns
  Pose T_W_B;                      // body (IMU) in world
  Vec3 v_W = Vec3::Zero();         // m/s, in W
  Vec3 b_g = Vec3::Zero();         // gyroscope bias, rad/s
  Vec3 b_a = Vec3::Zero();         // accelerometer bias, m/s^2
  bool has_velocity_bias = false;  // false when the source had poses only (TUM, 8-column csv)
};

enum class TrajectoryFormat { kTum, kEurocCsv };

/// Format from the file name: ".csv" -> EuRoC csv, anything else (".tum", ".txt") -> TUM.
TrajectoryFormat trajectoryFormatFromPath(const std::string& path);

/// Writes a whole trajectory. Throws InputError naming the file if it cannot be written.
void writeTum(const std::string& path, const std::vector<TrajectoryState>& states);
void writeEurocCsv(const std::string& path, const std::vector<TrajectoryState>& states);
void writeTrajectory(const std::string& path, const std::vector<TrajectoryState>& states,
                     TrajectoryFormat format);

/// One line of each format (no trailing newline), for streaming writers and logs.
std::string formatTumLine(const TrajectoryState& s);
std::string formatEurocCsvLine(const TrajectoryState& s);
/// The EuRoC csv header line (starting with '#').
const char* eurocCsvHeader();

/// Reads a trajectory. Throws InputError "<file>:<line>: ..." on a missing file, a wrong column count, an
/// unparsable number, a zero-norm quaternion or time stamps that do not strictly increase.
/// Large files are parsed on up to `max_threads` threads (0: all cores); the result does not depend on it.
std::vector<TrajectoryState> readTum(const std::string& path, int max_threads = 0);
std::vector<TrajectoryState> readEurocCsv(const std::string& path, int max_threads = 0);  // 17 or 8 columns
/// By file name as trajectoryFormatFromPath().
std::vector<TrajectoryState> readTrajectory(const std::string& path, int max_threads = 0);

/// Appends states to a file as they come (pipeline output). The file is created (truncated) on construction
/// and flushed on close() / destruction; each write() is one line.
class TrajectoryFileWriter {
 public:
  TrajectoryFileWriter(const std::string& path, TrajectoryFormat format);
  ~TrajectoryFileWriter();
  TrajectoryFileWriter(const TrajectoryFileWriter&) = delete;
  TrajectoryFileWriter& operator=(const TrajectoryFileWriter&) = delete;
  TrajectoryFileWriter(TrajectoryFileWriter&&) noexcept;
  TrajectoryFileWriter& operator=(TrajectoryFileWriter&&) noexcept;

  void write(const TrajectoryState& s);
  void flush();
  void close();  // throws InputError if data could not be written
  const std::string& path() const { return path_; }

 private:
  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  std::string path_;
  TrajectoryFormat format_;
  std::unique_ptr<std::FILE, Closer> file_;
};

}  // namespace linnet
