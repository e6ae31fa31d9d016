#include "bind_arrays.h"

namespace linnet::python {

py::dict resultsToArrays(const std::vector<FrameResult>& results, bool only_with_pose) {
  std::vector<const FrameResult*> sel;
  for (const FrameResult& r : results)
    if (!only_with_pose || r.estimate.has_pose) sel.push_back(&r);
  const py::ssize_t n = static_cast<py::ssize_t>(sel.size());
  py::array_t<std::int64_t> t(n);
  py::array_t<double> p({n, py::ssize_t(3)}), q({n, py::ssize_t(4)}), v({n, py::ssize_t(3)}),
      ba({n, py::ssize_t(3)}), bg({n, py::ssize_t(3)});
  py::array_t<bool> has_pose(n), keyframe(n);
  py::array_t<double> frontend_ms(n), backend_ms(n);
  py::array_t<int> points(n), lines(n);
  for (py::ssize_t i = 0; i < n; ++i) {
    const EstimatorOutput& e = sel[i]->estimate;
    t.mutable_at(i) = e.t;
    for (int k = 0; k < 3; ++k) {
      p.mutable_at(i, k) = sel[i]->T_W_B.p[k];
      v.mutable_at(i, k) = sel[i]->v_W[k];
      ba.mutable_at(i, k) = e.b_a[k];
      bg.mutable_at(i, k) = e.b_g[k];
    }
    q.mutable_at(i, 0) = sel[i]->T_W_B.q.x();
    q.mutable_at(i, 1) = sel[i]->T_W_B.q.y();
    q.mutable_at(i, 2) = sel[i]->T_W_B.q.z();
    q.mutable_at(i, 3) = sel[i]->T_W_B.q.w();
    has_pose.mutable_at(i) = e.has_pose;
    keyframe.mutable_at(i) = e.keyframe;
    frontend_ms.mutable_at(i) = sel[i]->frontend_ms;
    backend_ms.mutable_at(i) = sel[i]->backend_ms;
    points.mutable_at(i) = sel[i]->tracked_points;
    lines.mutable_at(i) = sel[i]->tracked_lines;
  }
  py::dict d;
  d["t_ns"] = t;
  d["position"] = p;
  d["quaternion_xyzw"] = q;
  d["velocity"] = v;
  d["bias_acc"] = ba;
  d["bias_gyr"] = bg;
  d["has_pose"] = has_pose;
  d["keyframe"] = keyframe;
  d["frontend_ms"] = frontend_ms;
  d["backend_ms"] = backend_ms;
  d["points"] = points;
  d["lines"] = lines;
  return d;
}

namespace {

py::array_t<double> pointsToArray(const std::vector<Vec3>& pts) {
  py::array_t<double> a({static_cast<py::ssize_t>(pts.size()), py::ssize_t(3)});
  for (std::size_t i = 0; i < pts.size(); ++i)
    for (int k = 0; k < 3; ++k) a.mutable_at(static_cast<py::ssize_t>(i), k) = pts[i][k];
  return a;
}

}  // namespace

py::dict mapToDict(const std::vector<Vec3>& points, const std::vector<MapLine>& lines) {
  const py::ssize_t n = static_cast<py::ssize_t>(lines.size());
  py::array_t<double> segs({n, py::ssize_t(2), py::ssize_t(3)});
  py::array_t<std::int64_t> ids(n);
  py::array_t<int> obs(n);
  py::array_t<double> sigma(n);
  for (py::ssize_t i = 0; i < n; ++i) {
    const MapLine& l = lines[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k) {
      segs.mutable_at(i, 0, k) = l.a[k];
      segs.mutable_at(i, 1, k) = l.b[k];
    }
    ids.mutable_at(i) = l.id;
    obs.mutable_at(i) = l.observations;
    sigma.mutable_at(i) = l.sigma_m;
  }
  py::dict d;
  d["points"] = pointsToArray(points);
  d["lines"] = segs;
  d["line_ids"] = ids;
  d["line_observations"] = obs;
  d["line_sigma_m"] = sigma;
  return d;
}

}  // namespace linnet::python
