#include "linnet/io/trajectory_io.h"

#include <cctype>
#include <cmath>
#include <string_view>

#include "linnet/core/error.h"
#include "linnet/io/text_parse.h"

namespace linnet {
namespace {

using io::formatDouble;

void appendNumber(std::string* out, double x) { out->append(formatDouble(x)); }

std::FILE* openForWriting(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) io::failInput(path, 0, "cannot open file for writing");
  return f;
}

void writeAll(const std::string& path, const std::string& text) {
  std::FILE* f = openForWriting(path);
  const std::size_t n = std::fwrite(text.data(), 1, text.size(), f);
  const bool ok = n == text.size() && std::fflush(f) == 0;
  std::fclose(f);
  if (!ok) io::failInput(path, 0, "write failed (disk full?)");
}

/// Quaternion from file values. Already-unit quaternions are kept bit for bit (exact round trips);
/// others (files written with few digits) are normalised. A (near) zero quaternion is an error.
Quat quaternionFromFile(const io::TextLines& file, double w, double x, double y, double z) {
  Quat q(w, x, y, z);
  const double n2 = q.squaredNorm();
  if (!std::isfinite(n2) || n2 < 1e-12) file.fail("quaternion has zero norm or is not finite");
  if (std::fabs(n2 - 1.0) > 1e-14) q.normalize();
  return q;
}

}  // namespace

TrajectoryFormat trajectoryFormatFromPath(const std::string& path) {
  const auto dot = path.rfind('.');
  if (dot != std::string::npos) {
    std::string ext = path.substr(dot + 1);
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext == "csv") return TrajectoryFormat::kEurocCsv;
  }
  return TrajectoryFormat::kTum;
}

const char* eurocCsvHeader() {
  return "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z [],"
         "v_RS_R_x [m s^-1],v_RS_R_y [m s^-1],v_RS_R_z [m s^-1],"
         "b_w_RS_S_x [rad s^-1],b_w_RS_S_y [rad s^-1],b_w_RS_S_z [rad s^-1],"
         "b_a_RS_S_x [m s^-2],b_a_RS_S_y [m s^-2],b_a_RS_S_z [m s^-2]";
}

std::string formatTumLine(const TrajectoryState& s) {
  std::string line = io::formatSeconds(s.t);
  const Vec3& p = s.T_W_B.p;
  const Quat& q = s.T_W_B.q;
  for (double v : {p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w()}) {
    line.push_back(' ');
    appendNumber(&line, v);
  }
  return line;
}

std::string formatEurocCsvLine(const TrajectoryState& s) {
  std::string line = std::to_string(s.t);
  const Vec3& p = s.T_W_B.p;
  const Quat& q = s.T_W_B.q;
  const double values[16] = {p.x(),     p.y(),     p.z(),     q.w(),     q.x(),     q.y(),
                             q.z(),     s.v_W.x(), s.v_W.y(), s.v_W.z(), s.b_g.x(), s.b_g.y(),
                             s.b_g.z(), s.b_a.x(), s.b_a.y(), s.b_a.z()};
  for (double v : values) {
    line.push_back(',');
    appendNumber(&line, v);
  }
  return line;
}

void writeTum(const std::string& path, const std::vector<TrajectoryState>& states) {
  std::string text = "# timestamp[s] tx ty tz qx qy qz qw (T_W_B: body in world, Hamilton quaternion)\n";
  text.reserve(states.size() * 120 + text.size());
  for (const auto& s : states) text.append(formatTumLine(s)).push_back('\n');
  writeAll(path, text);
}

void writeEurocCsv(const std::string& path, const std::vector<TrajectoryState>& states) {
  std::string text = std::string(eurocCsvHeader()) + "\n";
  text.reserve(states.size() * 250 + text.size());
  for (const auto& s : states) text.append(formatEurocCsvLine(s)).push_back('\n');
  writeAll(path, text);
}

void writeTrajectory(const std::string& path, const std::vector<TrajectoryState>& states,
                     TrajectoryFormat format) {
  if (format == TrajectoryFormat::kEurocCsv)
    writeEurocCsv(path, states);
  else
    writeTum(path, states);
}

std::vector<TrajectoryState> readTum(const std::string& path, int max_threads) {
  const io::TextFile file = io::TextFile::read(path);
  static const char* kNames[8] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
  auto parse = [](const io::TextLines& lines, std::string_view line) {
    std::string_view f[8];
    const int n = io::splitFields(line, ' ', f, 8);
    if (n != 8) lines.fail("expected 8 columns 't x y z qx qy qz qw', got " + std::to_string(n));
    TrajectoryState s;
    if (!io::parseSecondsToNs(f[0], &s.t))
      lines.fail("column 'timestamp': expected seconds, got '" + std::string(f[0]) + "'");
    double v[7];
    for (int i = 0; i < 7; ++i) v[i] = io::parseDoubleField(lines, f[i + 1], kNames[i + 1]);
    s.T_W_B.p = Vec3(v[0], v[1], v[2]);
    s.T_W_B.q = quaternionFromFile(lines, v[6], v[3], v[4], v[5]);
    return s;
  };
  std::vector<TrajectoryState> states =
      io::parseRows<TrajectoryState>(file, io::parseThreads(file.sizeBytes(), max_threads), parse, 80);
  io::checkStrictlyIncreasing(file, states, [](const TrajectoryState& s) { return s.t; });
  return states;
}

std::vector<TrajectoryState> readEurocCsv(const std::string& path, int max_threads) {
  const io::TextFile file = io::TextFile::read(path);
  static const char* kNames[17] = {"timestamp", "p_x",   "p_y",   "p_z",   "q_w",  "q_x",
                                   "q_y",       "q_z",   "v_x",   "v_y",   "v_z",  "b_w_x",
                                   "b_w_y",     "b_w_z", "b_a_x", "b_a_y", "b_a_z"};
  // The first data row fixes the column count (17 or 8); every row must have the same.
  int columns = 0;
  {
    io::TextLines lines = file.lines();
    std::string_view line;
    std::string_view f[17];
    if (lines.nextData(&line)) {
      columns = io::splitFields(line, ',', f, 17);
      if (columns != 17 && columns != 8)
        lines.fail("expected 17 (t, p, q, v, b_w, b_a) or 8 (t, p, q) columns, got " +
                   std::to_string(columns));
    }
  }
  auto parse = [columns](const io::TextLines& lines, std::string_view line) {
    std::string_view f[17];
    const int n = io::splitFields(line, ',', f, 17);
    if (n != columns)
      lines.fail("expected " + std::to_string(columns) + " columns like the first row, got " +
                 std::to_string(n));
    TrajectoryState s;
    s.t = io::parseInt64Field(lines, f[0], kNames[0]);
    double v[16];
    for (int i = 1; i < n; ++i) v[i - 1] = io::parseDoubleField(lines, f[i], kNames[i]);
    s.T_W_B.p = Vec3(v[0], v[1], v[2]);
    s.T_W_B.q = quaternionFromFile(lines, v[3], v[4], v[5], v[6]);
    if (n == 17) {
      s.v_W = Vec3(v[7], v[8], v[9]);
      s.b_g = Vec3(v[10], v[11], v[12]);
      s.b_a = Vec3(v[13], v[14], v[15]);
      s.has_velocity_bias = true;
    }
    return s;
  };
  std::vector<TrajectoryState> states =
      io::parseRows<TrajectoryState>(file, io::parseThreads(file.sizeBytes(), max_threads), parse, 150);
  io::checkStrictlyIncreasing(file, states, [](const TrajectoryState& s) { return s.t; });
  return states;
}

std::vector<TrajectoryState> readTrajectory(const std::string& path, int max_threads) {
  return trajectoryFormatFromPath(path) == TrajectoryFormat::kEurocCsv ? readEurocCsv(path, max_threads)
                                                                       : readTum(path, max_threads);
}

TrajectoryFileWriter::TrajectoryFileWriter(const std::string& path, TrajectoryFormat format)
    : path_(path), format_(format), file_(openForWriting(path)) {
  if (format_ == TrajectoryFormat::kEurocCsv) {
    std::fputs(eurocCsvHeader(), file_.get());
  } else {
    std::fputs("# timestamp[s] tx ty tz qx qy qz qw (T_W_B: body in world, Hamilton quaternion)",
               file_.get());
  }
  std::fputc('\n', file_.get());
}

TrajectoryFileWriter::~TrajectoryFileWriter() = default;
TrajectoryFileWriter::TrajectoryFileWriter(TrajectoryFileWriter&&) noexcept = default;
TrajectoryFileWriter& TrajectoryFileWriter::operator=(TrajectoryFileWriter&&) noexcept = default;

void TrajectoryFileWriter::write(const TrajectoryState& s) {
  if (!file_) throw UsageError("TrajectoryFileWriter::write on a closed writer (" + path_ + ")");
  const std::string line = format_ == TrajectoryFormat::kEurocCsv ? formatEurocCsvLine(s) : formatTumLine(s);
  if (std::fputs(line.c_str(), file_.get()) < 0 || std::fputc('\n', file_.get()) == EOF)
    io::failInput(path_, 0, "write failed");
}

void TrajectoryFileWriter::flush() {
  if (file_) std::fflush(file_.get());
}

void TrajectoryFileWriter::close() {
  if (!file_) return;
  const bool ok = std::fflush(file_.get()) == 0 && !std::ferror(file_.get());
  file_.reset();
  if (!ok) io::failInput(path_, 0, "write failed (disk full?)");
}

}  // namespace linnet
