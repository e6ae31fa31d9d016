// The System's compact per-frame results (see result_log.h).
#include "linnet/pipeline/result_log.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

namespace linnet {

bool ResultLog::samePose(const Pose& a, const Pose& b) {
  // Bit for bit (a signed zero would print differently after a product).
  return std::memcmp(a.q.coeffs().data(), b.q.coeffs().data(), 4 * sizeof(double)) == 0 &&
         std::memcmp(a.p.data(), b.p.data(), 3 * sizeof(double)) == 0;
}

template <class T>
const T* ResultLog::inForce(const std::vector<std::pair<std::size_t, T>>& list, std::size_t i) {
  const auto it = std::upper_bound(list.begin(), list.end(), i,
                                   [](std::size_t x, const std::pair<std::size_t, T>& e) { return x < e.first; });
  return it == list.begin() ? nullptr : &std::prev(it)->second;
}

void ResultLog::push(const FrameResult& r, const std::optional<Pose>& correction) {
  const EstimatorOutput& e = r.estimate;
  const std::size_t i = size_;
  if (i % kBlock == 0) blocks_.push_back(std::make_unique<Record[]>(kBlock));  // value-initialised records
  Record& rec = blocks_[i / kBlock][i % kBlock];
  rec.T_W_B = e.T_W_B;
  rec.t = e.t;
  rec.v_W = e.v_W;
  rec.b_a = e.b_a;
  rec.b_g = e.b_g;
  rec.num_points = e.num_points;
  rec.num_lines = e.num_lines;
  rec.reidentified_lines = e.reidentified_lines;
  rec.reinitialisations = e.reinitialisations;
  rec.tracked_points = r.tracked_points;
  rec.stereo_points = r.stereo_points;
  rec.tracked_lines = r.tracked_lines;
  rec.status = static_cast<std::uint8_t>(e.status);
  rec.has_pose = e.has_pose;
  rec.keyframe = e.keyframe;
  rec.corrected = correction.has_value();
  rec.est_line_ms = static_cast<float>(e.line_ms);
  rec.est_solver_ms = static_cast<float>(e.solver_ms);
  rec.est_solve_ms = static_cast<float>(e.solve_ms);
  rec.point_ms = static_cast<float>(r.point_ms);
  rec.line_ms = static_cast<float>(r.line_ms);
  rec.frontend_ms = static_cast<float>(r.frontend_ms);
  rec.backend_ms = static_cast<float>(r.backend_ms);
  rec.point_cpu_ms = static_cast<float>(r.point_cpu_ms);
  rec.line_cpu_ms = static_cast<float>(r.line_cpu_ms);
  rec.backend_cpu_ms = static_cast<float>(r.backend_cpu_ms);
  rec.loop_cpu_ms = static_cast<float>(r.loop_cpu_ms);
  rec.rss_mb = static_cast<float>(r.rss_mb);
  ++size_;

  const Calibration* last = calibrations_.empty() ? nullptr : &calibrations_.back().second;
  if (!last || !samePose(last->T_B_R, e.T_B_R) || !samePose(last->S_C1, e.S_C1) ||
      std::memcmp(&last->time_offset_s, &e.time_offset_s, sizeof(double)) != 0)
    calibrations_.emplace_back(i, Calibration{e.T_B_R, e.S_C1, e.time_offset_s});
  if (correction && !recorrected_ && (corrections_.empty() || !samePose(corrections_.back().second, *correction)))
    corrections_.emplace_back(i, *correction);
}

void ResultLog::recorrect(const std::function<Pose(Timestamp)>& final) {
  corrections_.clear();
  for (std::size_t i = 0; i < size_; ++i) {
    if (!record(i).has_pose) continue;
    const Pose C = final(record(i).t);
    if (corrections_.empty() || !samePose(corrections_.back().second, C)) corrections_.emplace_back(i, C);
  }
  recorrected_ = true;
}

FrameResult ResultLog::at(std::size_t i) const {
  if (i >= size_) throw std::out_of_range("ResultLog::at: no result " + std::to_string(i));
  const Record& rec = record(i);
  FrameResult r;
  EstimatorOutput& e = r.estimate;
  e.t = rec.t;
  e.status = static_cast<TrackingStatus>(rec.status);
  e.has_pose = rec.has_pose;
  e.T_W_B = rec.T_W_B;
  e.v_W = rec.v_W;
  e.b_a = rec.b_a;
  e.b_g = rec.b_g;
  e.keyframe = rec.keyframe;
  e.num_points = rec.num_points;
  e.num_lines = rec.num_lines;
  e.reidentified_lines = rec.reidentified_lines;
  e.line_ms = rec.est_line_ms;
  e.solver_ms = rec.est_solver_ms;
  e.reinitialisations = rec.reinitialisations;
  if (const Calibration* c = inForce(calibrations_, i)) {
    e.T_B_R = c->T_B_R;
    e.S_C1 = c->S_C1;
    e.time_offset_s = c->time_offset_s;
  }
  e.solve_ms = rec.est_solve_ms;

  r.T_W_B = e.T_W_B;
  r.v_W = e.v_W;
  const bool corrected = recorrected_ ? rec.has_pose : rec.corrected;
  const Pose* C = corrected ? inForce(corrections_, i) : nullptr;
  if (C) {
    r.T_W_B = *C * e.T_W_B;
    r.v_W = C->q * e.v_W;
  }
  r.tracked_points = rec.tracked_points;
  r.stereo_points = rec.stereo_points;
  r.tracked_lines = rec.tracked_lines;
  r.point_ms = rec.point_ms;
  r.line_ms = rec.line_ms;
  r.frontend_ms = rec.frontend_ms;
  r.backend_ms = rec.backend_ms;
  r.line_backend_ms = rec.est_line_ms;
  r.solver_ms = rec.est_solver_ms;
  r.point_cpu_ms = rec.point_cpu_ms;
  r.line_cpu_ms = rec.line_cpu_ms;
  r.backend_cpu_ms = rec.backend_cpu_ms;
  r.loop_cpu_ms = rec.loop_cpu_ms;
  r.rss_mb = rec.rss_mb;
  return r;
}

std::size_t ResultLog::bytes() const {
  return blocks_.size() * kBlock * sizeof(Record) + blocks_.capacity() * sizeof(blocks_[0]) +
         calibrations_.capacity() * sizeof(calibrations_[0]) +
         corrections_.capacity() * sizeof(corrections_[0]);
}

}  // namespace linnet
