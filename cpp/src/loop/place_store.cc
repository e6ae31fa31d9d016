// The loop closer's compact place descriptions (see place_store.h).
#include "linnet/loop/place_store.h"

#include <limits>

namespace linnet {

namespace {

template <class T>
std::size_t heapBytes(const std::vector<T>& v) {
  return v.capacity() * sizeof(T);
}

std::size_t heapBytes(const cv::Mat& m) { return m.empty() ? 0 : m.total() * m.elemSize(); }

}  // namespace

std::size_t StoredPlace::bytes() const {
  return heapBytes(uv) + heapBytes(descriptors_2d) + heapBytes(p_C) + heapBytes(rows_3d) + heapBytes(descriptors_3d) +
         heapBytes(line_uv) + heapBytes(line_desc) + heapBytes(line_p_C);
}

StoredPlace storePlace(const PlaceFeatures& f, int max_detected) {
  StoredPlace s;
  // The rows kept: every tracked corner's, and the first max_detected of the others.
  const int n = static_cast<int>(f.uv.size());
  if (f.descriptors_2d.rows != n) max_detected = -1;  // rows that do not pair up: kept as they are
  std::vector<bool> tracked(static_cast<std::size_t>(n), false);
  for (int r : f.tracked_rows)
    if (r >= 0 && r < n) tracked[static_cast<std::size_t>(r)] = true;
  std::vector<int> kept_row(static_cast<std::size_t>(n), -1);  // row in the stored place, -1: dropped
  std::vector<int> rows;
  int detected = 0;
  for (int r = 0; r < n; ++r) {
    if (!tracked[static_cast<std::size_t>(r)] && max_detected >= 0 && detected++ >= max_detected) continue;
    kept_row[static_cast<std::size_t>(r)] = static_cast<int>(rows.size());
    rows.push_back(r);
  }
  s.uv.reserve(rows.size());
  for (int r : rows) s.uv.push_back(f.uv[static_cast<std::size_t>(r)].cast<float>());
  if (static_cast<int>(rows.size()) == f.descriptors_2d.rows) {
    s.descriptors_2d = f.descriptors_2d.clone();
  } else {
    s.descriptors_2d.create(static_cast<int>(rows.size()), f.descriptors_2d.cols, f.descriptors_2d.type());
    for (std::size_t i = 0; i < rows.size(); ++i)
      f.descriptors_2d.row(rows[i]).copyTo(s.descriptors_2d.row(static_cast<int>(i)));
  }
  s.p_C.reserve(f.p_C.size());
  for (const Vec3& p : f.p_C) s.p_C.push_back(p.cast<float>());
  bool known = f.rows_3d.size() == f.p_C.size() && rows.size() <= std::numeric_limits<std::uint16_t>::max();
  for (std::size_t i = 0; known && i < f.rows_3d.size(); ++i)
    known = f.rows_3d[i] >= 0 && f.rows_3d[i] < n && kept_row[static_cast<std::size_t>(f.rows_3d[i])] >= 0;
  if (known) {
    s.rows_3d.reserve(f.rows_3d.size());
    for (int r : f.rows_3d) s.rows_3d.push_back(static_cast<std::uint16_t>(kept_row[static_cast<std::size_t>(r)]));
  } else {
    s.descriptors_3d = f.descriptors_3d.clone();
  }
  s.line_uv.reserve(f.line_uv.size());
  for (const auto& l : f.line_uv) s.line_uv.push_back({l[0].cast<float>(), l[1].cast<float>()});
  s.line_desc = f.line_desc;
  s.line_desc.shrink_to_fit();
  s.line_p_C.reserve(f.line_p_C.size());
  for (const auto& l : f.line_p_C) s.line_p_C.push_back({l[0].cast<float>(), l[1].cast<float>()});
  return s;
}

PlaceFeatures expandPlace(const StoredPlace& s) {
  PlaceFeatures f;
  f.uv.reserve(s.uv.size());
  for (const Eigen::Vector2f& u : s.uv) f.uv.push_back(u.cast<double>());
  f.descriptors_2d = s.descriptors_2d;  // shared, read only
  f.p_C.reserve(s.p_C.size());
  for (const Eigen::Vector3f& p : s.p_C) f.p_C.push_back(p.cast<double>());
  if (!s.rows_3d.empty()) {
    f.descriptors_3d.create(static_cast<int>(s.rows_3d.size()), s.descriptors_2d.cols, s.descriptors_2d.type());
    for (std::size_t i = 0; i < s.rows_3d.size(); ++i)
      s.descriptors_2d.row(s.rows_3d[i]).copyTo(f.descriptors_3d.row(static_cast<int>(i)));
  } else {
    f.descriptors_3d = s.descriptors_3d;
  }
  f.rows_3d.assign(s.rows_3d.begin(), s.rows_3d.end());
  f.line_uv.reserve(s.line_uv.size());
  for (const auto& l : s.line_uv) f.line_uv.push_back({l[0].cast<double>(), l[1].cast<double>()});
  f.line_desc = s.line_desc;
  f.line_p_C.reserve(s.line_p_C.size());
  for (const auto& l : s.line_p_C) f.line_p_C.push_back({l[0].cast<double>(), l[1].cast<double>()});
  return f;
}

}  // namespace linnet
