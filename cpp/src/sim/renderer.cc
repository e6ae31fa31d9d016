#include "linnet/sim/renderer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "linnet/core/error.h"
#include "linnet/core/options.h"

namespace linnet::sim {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

/// One quad prepared for a given camera pose: edge functions of its projected (clipped) polygon in normalised
/// coordinates, the plane's inverse-depth coefficients and the texture-coordinate (dual basis) coefficients.
struct PreparedQuad {
  int index = -1;
  int n_edges = 0;
  std::array<float, 3 * 6> edge{};     // A, B, C per edge: inside <=> A x + B y + C >= 0 for every edge
  float xmin = 0, xmax = 0, ymin = 0, ymax = 0;  // bounding box of the projected polygon
  std::array<float, 3> w{};            // 1/z = w0 x + w1 y + w2
};

/// Per-quad shading data in the camera frame (double: computed once per quad per frame).
struct ShadingQuad {
  std::array<float, 3> a{}, b{};  // s = (a . r) / w - a0, t = (b . r) / w - b0, r = (x, y, 1)
  float a0 = 0, b0 = 0;
  std::array<float, 3> n{};       // unit normal in the camera frame
  float lod_scale = 0;            // texels per sample at depth 1 m, frontal view
  const Texture* texture = nullptr;
  float shade = 1;
};

/// Counter-based random numbers (SplitMix64 finaliser): the same (seed, counter) always gives the same bits.
inline std::uint64_t mix64(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

/// Approximately standard-normal value from 64 random bits (sum of four 16-bit uniforms, Irwin-Hall, unit variance).
inline float gaussFromBits(std::uint64_t bits) {
  const float s = static_cast<float>(bits & 0xFFFF) + static_cast<float>((bits >> 16) & 0xFFFF) +
                  static_cast<float>((bits >> 32) & 0xFFFF) + static_cast<float>((bits >> 48) & 0xFFFF);
  return (s * (1.0f / 65536.0f) - 2.0f) * 1.7320508f;
}

inline float sampleBilinear(const cv::Mat& img, float u, float v) {
  const int w = img.cols, h = img.rows;
  u = std::clamp(u, 0.0f, static_cast<float>(w - 1));
  v = std::clamp(v, 0.0f, static_cast<float>(h - 1));
  const int x0 = std::min(static_cast<int>(u), w - 2);
  const int y0 = std::min(static_cast<int>(v), h - 2);
  const float fx = u - static_cast<float>(x0), fy = v - static_cast<float>(y0);
  const std::uint8_t* r0 = img.ptr<std::uint8_t>(y0) + x0;
  const std::uint8_t* r1 = r0 + img.step[0];
  const float top = static_cast<float>(r0[0]) + fx * (static_cast<float>(r0[1]) - static_cast<float>(r0[0]));
  const float bot = static_cast<float>(r1[0]) + fx * (static_cast<float>(r1[1]) - static_cast<float>(r1[0]));
  return top + fy * (bot - top);
}

/// Clips a polygon (camera frame) to z >= near (Sutherland-Hodgman against one plane).
int clipNear(const std::array<Vec3, 4>& in, double near, std::array<Vec3, 8>* out) {
  int n = 0;
  for (int i = 0; i < 4; ++i) {
    const Vec3& a = in[static_cast<std::size_t>(i)];
    const Vec3& b = in[static_cast<std::size_t>((i + 1) % 4)];
    const bool ina = a.z() >= near, inb = b.z() >= near;
    if (ina) (*out)[static_cast<std::size_t>(n++)] = a;
    if (ina != inb) {
      const double t = (near - a.z()) / (b.z() - a.z());
      (*out)[static_cast<std::size_t>(n++)] = a + t * (b - a);
    }
  }
  return n;
}

/// Texture lookup of one sample of quad `sq` along ray (x, y, 1) at inverse depth w. `lod2` scales the squared
/// footprint (sub-samples are smaller than pixels; the user's mip bias).
inline float shadeSample(const ShadingQuad& sq, float x, float y, float w, float lod2) {
  const float z = 1.0f / w;
  const float s = (sq.a[0] * x + sq.a[1] * y + sq.a[2]) * z - sq.a0;
  const float t = (sq.b[0] * x + sq.b[1] * y + sq.b[2]) * z - sq.b0;
  // Mip level from the footprint: texels per sample ~ z * lod_scale / sqrt(cos(incidence)), a compromise between the
  // two axes of the anisotropic footprint on oblique surfaces. Level L covers footprints in [2^(L-1/2), 2^(L+1/2)).
  const float rn2 = x * x + y * y + 1.0f;
  const float ndot = sq.n[0] * x + sq.n[1] * y + sq.n[2];
  const float cos2 = std::max(0.0025f, ndot * ndot / rn2);
  float f2 = z * z * sq.lod_scale * sq.lod_scale * lod2 / std::sqrt(cos2);
  int level = 0;
  const int max_level = sq.texture->levels() - 1;
  while (f2 > 2.0f && level < max_level) {
    f2 *= 0.25f;
    ++level;
  }
  const cv::Mat& img = sq.texture->level(level);
  return sq.shade *
         sampleBilinear(img, s * static_cast<float>(img.cols) - 0.5f, t * static_cast<float>(img.rows) - 0.5f);
}

}  // namespace

struct Renderer::Raster {
  std::vector<float> w;              // inverse depth of the nearest surface per sample (0 = none)
  std::vector<int> id;               // quad index per sample (-1 = none)
  std::vector<ShadingQuad> shading;  // per quad of the scene (valid where some sample refers to it)
  std::vector<PreparedQuad> prepared;  // per quad of the scene (n_edges == 0: not visible)
  std::vector<int> visible;            // indices of the prepared quads
};

namespace {
/// The nearest of the quads `ids[0..n)` hit by ray (x, y, 1): returns its index (or -1) and its inverse depth.
inline int nearestHit(const std::vector<PreparedQuad>& prepared, const int* ids, int n, float x, float y,
                      float* w_out) {
  float best_w = 0.0f;
  int best = -1;
  for (int k = 0; k < n; ++k) {
    const PreparedQuad& pq = prepared[static_cast<std::size_t>(ids[k])];
    bool in = true;
    for (int e = 0; e < pq.n_edges && in; ++e) {
      const float* E = &pq.edge[static_cast<std::size_t>(3 * e)];
      in = E[0] * x + E[1] * y + E[2] >= 0.0f;
    }
    if (!in) continue;
    const float w = pq.w[0] * x + pq.w[1] * y + pq.w[2];
    if (w > best_w) {
      best_w = w;
      best = pq.index;
    }
  }
  *w_out = best_w;
  return best;
}
}  // namespace

Renderer::Renderer(const CameraModel& camera, const RenderOptions& options) : options_(options) {
  validateOptions(options_, "render");
  width_ = camera.width();
  height_ = camera.height();
  if (width_ < 2 || height_ < 2) throw ConfigError("render: camera image size must be at least 2x2");
  grid_ss_ = makeGrid(camera, options_.supersample);
  grid_1_ = makeGrid(camera, 1);
  vignette_.resize(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_));
  // Mild radial fall-off around the principal point, normalised to the farthest image corner.
  const double cx = camera.cx(), cy = camera.cy();
  double r2max = 0.0;
  for (double x : {0.0, width_ - 1.0})
    for (double y : {0.0, height_ - 1.0}) r2max = std::max(r2max, (x - cx) * (x - cx) + (y - cy) * (y - cy));
  for (int r = 0; r < height_; ++r)
    for (int c = 0; c < width_; ++c) {
      const double r2 = ((c - cx) * (c - cx) + (r - cy) * (r - cy)) / r2max;
      vignette_[static_cast<std::size_t>(r * width_ + c)] = static_cast<float>(1.0 - options_.vignetting * r2);
    }
}

Renderer::RayGrid Renderer::makeGrid(const CameraModel& camera, int ss) {
  RayGrid g;
  g.cols = camera.width() * ss;
  g.rows = camera.height() * ss;
  const std::size_t n = static_cast<std::size_t>(g.cols) * static_cast<std::size_t>(g.rows);
  g.x.assign(n, kNaN);
  g.y.assign(n, kNaN);
  g.xmin = g.ymin = std::numeric_limits<float>::max();
  g.xmax = g.ymax = std::numeric_limits<float>::lowest();
  for (int r = 0; r < g.rows; ++r)
    for (int c = 0; c < g.cols; ++c) {
      // Pixel centres at integer coordinates; the ss x ss samples of a pixel are spread evenly inside it.
      const Vec2 px((c + 0.5) / ss - 0.5, (r + 0.5) / ss - 0.5);
      Vec2 uv;
      if (!camera.undistort(px, &uv) || !uv.allFinite()) continue;
      const std::size_t i = static_cast<std::size_t>(r) * static_cast<std::size_t>(g.cols) + static_cast<std::size_t>(c);
      g.x[i] = static_cast<float>(uv.x());
      g.y[i] = static_cast<float>(uv.y());
      g.xmin = std::min(g.xmin, g.x[i]);
      g.xmax = std::max(g.xmax, g.x[i]);
      g.ymin = std::min(g.ymin, g.y[i]);
      g.ymax = std::max(g.ymax, g.y[i]);
    }
  g.tiles_x = (g.cols + g.tile - 1) / g.tile;
  g.tiles_y = (g.rows + g.tile - 1) / g.tile;
  g.tile_box.assign(static_cast<std::size_t>(g.tiles_x * g.tiles_y) * 4, 0.0f);
  for (int ty = 0; ty < g.tiles_y; ++ty)
    for (int tx = 0; tx < g.tiles_x; ++tx) {
      float x0 = std::numeric_limits<float>::max(), x1 = std::numeric_limits<float>::lowest();
      float y0 = x0, y1 = x1;
      for (int r = ty * g.tile; r < std::min(g.rows, (ty + 1) * g.tile); ++r)
        for (int c = tx * g.tile; c < std::min(g.cols, (tx + 1) * g.tile); ++c) {
          const std::size_t i = static_cast<std::size_t>(r) * static_cast<std::size_t>(g.cols) + static_cast<std::size_t>(c);
          if (std::isnan(g.x[i])) continue;
          x0 = std::min(x0, g.x[i]);
          x1 = std::max(x1, g.x[i]);
          y0 = std::min(y0, g.y[i]);
          y1 = std::max(y1, g.y[i]);
        }
      float* box = &g.tile_box[static_cast<std::size_t>(ty * g.tiles_x + tx) * 4];
      box[0] = x0, box[1] = x1, box[2] = y0, box[3] = y1;  // empty tile: x0 > x1, never overlaps
    }
  g.col_box.assign(static_cast<std::size_t>(g.tiles_x) * 2, 0.0f);
  g.row_box.assign(static_cast<std::size_t>(g.tiles_y) * 2, 0.0f);
  for (int tx = 0; tx < g.tiles_x; ++tx) {
    float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
    for (int ty = 0; ty < g.tiles_y; ++ty) {
      const float* box = &g.tile_box[static_cast<std::size_t>(ty * g.tiles_x + tx) * 4];
      if (box[0] <= box[1]) lo = std::min(lo, box[0]), hi = std::max(hi, box[1]);
    }
    g.col_box[static_cast<std::size_t>(2 * tx)] = lo, g.col_box[static_cast<std::size_t>(2 * tx + 1)] = hi;
  }
  for (int ty = 0; ty < g.tiles_y; ++ty) {
    float lo = std::numeric_limits<float>::max(), hi = std::numeric_limits<float>::lowest();
    for (int tx = 0; tx < g.tiles_x; ++tx) {
      const float* box = &g.tile_box[static_cast<std::size_t>(ty * g.tiles_x + tx) * 4];
      if (box[2] <= box[3]) lo = std::min(lo, box[2]), hi = std::max(hi, box[3]);
    }
    g.row_box[static_cast<std::size_t>(2 * ty)] = lo, g.row_box[static_cast<std::size_t>(2 * ty + 1)] = hi;
  }
  g.samples_per_unit = 0.5 * (camera.fx() + camera.fy()) * ss;
  return g;
}

void Renderer::rasterise(const Scene& scene, const Pose& T_W_C, const RayGrid& g, Raster* raster) const {
  const std::size_t n = g.x.size();
  raster->w.assign(n, 0.0f);
  raster->id.assign(n, -1);
  raster->shading.assign(scene.quads().size(), ShadingQuad{});
  raster->prepared.assign(scene.quads().size(), PreparedQuad{});
  raster->visible.clear();
  const Mat3 R_C_W = T_W_C.R().transpose();
  const Vec3 p_W_C = T_W_C.p;
  const auto& quads = scene.quads();
  std::vector<int> cols, rows;
  cols.reserve(static_cast<std::size_t>(g.tiles_x));
  rows.reserve(static_cast<std::size_t>(g.tiles_y));
  for (std::size_t qi = 0; qi < quads.size(); ++qi) {
    const Quad& q = quads[qi];
    const Vec3 o = R_C_W * (q.origin - p_W_C);
    const Vec3 u = R_C_W * q.axis_u;
    const Vec3 v = R_C_W * q.axis_v;
    const std::array<Vec3, 4> corners{o, o + u, o + u + v, o + v};
    if (std::max({corners[0].z(), corners[1].z(), corners[2].z(), corners[3].z()}) < options_.near_m) continue;
    const Vec3 nrm = u.cross(v);
    const double d = nrm.dot(o);
    if (std::abs(d) < 1e-12 * nrm.norm()) continue;  // plane through the optical centre: seen edge-on
    std::array<Vec3, 8> clipped;
    const int m = clipNear(corners, options_.near_m, &clipped);
    if (m < 3) continue;
    PreparedQuad pq;
    pq.index = static_cast<int>(qi);
    std::array<Vec2, 8> poly;
    double area = 0.0;
    pq.xmin = pq.ymin = std::numeric_limits<float>::max();
    pq.xmax = pq.ymax = std::numeric_limits<float>::lowest();
    for (int k = 0; k < m; ++k) {
      const Vec3& P = clipped[static_cast<std::size_t>(k)];
      poly[static_cast<std::size_t>(k)] = Vec2(P.x() / P.z(), P.y() / P.z());
    }
    for (int k = 0; k < m; ++k) {
      const Vec2& a = poly[static_cast<std::size_t>(k)];
      const Vec2& b = poly[static_cast<std::size_t>((k + 1) % m)];
      area += a.x() * b.y() - b.x() * a.y();
      pq.xmin = std::min(pq.xmin, static_cast<float>(a.x()));
      pq.xmax = std::max(pq.xmax, static_cast<float>(a.x()));
      pq.ymin = std::min(pq.ymin, static_cast<float>(a.y()));
      pq.ymax = std::max(pq.ymax, static_cast<float>(a.y()));
    }
    if (std::abs(area) < 1e-14) continue;
    if (pq.xmax < g.xmin || pq.xmin > g.xmax || pq.ymax < g.ymin || pq.ymin > g.ymax) continue;  // outside the view
    const double orient = area > 0.0 ? 1.0 : -1.0;
    pq.n_edges = 0;
    for (int k = 0; k < m; ++k) {
      const Vec2& a = poly[static_cast<std::size_t>(k)];
      const Vec2& b = poly[static_cast<std::size_t>((k + 1) % m)];
      const Vec2 e = b - a;
      if (e.squaredNorm() < 1e-24) continue;
      // E(p) = e x (p - a) = -e.y p.x + e.x p.y + (e.y a.x - e.x a.y), positive inside a counter-clockwise polygon.
      const double len = e.norm();
      float* E = &pq.edge[static_cast<std::size_t>(3 * pq.n_edges++)];
      E[0] = static_cast<float>(orient * -e.y() / len);
      E[1] = static_cast<float>(orient * e.x() / len);
      E[2] = static_cast<float>(orient * (e.y() * a.x() - e.x() * a.y()) / len);
    }
    const Vec3 wc = nrm / d;
    {
      // Texture coordinates by the dual basis of (u, v) in the quad's plane: s = a . (X - o), t = b . (X - o).
      ShadingQuad& sq = raster->shading[qi];
      const double nn = nrm.squaredNorm();
      const Vec3 a = v.cross(nrm) / nn, b = nrm.cross(u) / nn;
      sq.a = {static_cast<float>(a.x()), static_cast<float>(a.y()), static_cast<float>(a.z())};
      sq.b = {static_cast<float>(b.x()), static_cast<float>(b.y()), static_cast<float>(b.z())};
      sq.a0 = static_cast<float>(a.dot(o));
      sq.b0 = static_cast<float>(b.dot(o));
      const Vec3 nu = nrm / std::sqrt(nn);
      sq.n = {static_cast<float>(nu.x()), static_cast<float>(nu.y()), static_cast<float>(nu.z())};
      sq.texture = &scene.textures()[static_cast<std::size_t>(q.texture)];
      const double texel_m = std::min(u.norm() / sq.texture->width(), v.norm() / sq.texture->height());
      sq.lod_scale = static_cast<float>(1.0 / (g.samples_per_unit * texel_m));
      sq.shade = static_cast<float>(q.shade);
    }
    pq.w = {static_cast<float>(wc.x()), static_cast<float>(wc.y()), static_cast<float>(wc.z())};
    raster->prepared[qi] = pq;
    raster->visible.push_back(pq.index);

    // Candidate tiles: the columns and rows of tiles whose ray bounds overlap the polygon's bounding box.
    cols.clear();
    rows.clear();
    for (int tx = 0; tx < g.tiles_x; ++tx)
      if (g.col_box[static_cast<std::size_t>(2 * tx + 1)] >= pq.xmin && g.col_box[static_cast<std::size_t>(2 * tx)] <= pq.xmax)
        cols.push_back(tx);
    for (int ty = 0; ty < g.tiles_y; ++ty)
      if (g.row_box[static_cast<std::size_t>(2 * ty + 1)] >= pq.ymin && g.row_box[static_cast<std::size_t>(2 * ty)] <= pq.ymax)
        rows.push_back(ty);
    for (const int ty : rows)
      for (const int tx : cols) {
        const float* box = &g.tile_box[static_cast<std::size_t>(ty * g.tiles_x + tx) * 4];
        if (box[1] < pq.xmin || box[0] > pq.xmax || box[3] < pq.ymin || box[2] > pq.ymax) continue;
        bool outside = false, inside = true;
        for (int k = 0; k < pq.n_edges; ++k) {
          const float* E = &pq.edge[static_cast<std::size_t>(3 * k)];
          const float hi = E[0] * (E[0] > 0 ? box[1] : box[0]) + E[1] * (E[1] > 0 ? box[3] : box[2]) + E[2];
          const float lo = E[0] * (E[0] > 0 ? box[0] : box[1]) + E[1] * (E[1] > 0 ? box[2] : box[3]) + E[2];
          if (hi < 0.0f) {
            outside = true;
            break;
          }
          if (lo < 0.0f) inside = false;
        }
        if (outside) continue;
        const int r0 = ty * g.tile, r1 = std::min(g.rows, r0 + g.tile);
        const int c0 = tx * g.tile, c1 = std::min(g.cols, c0 + g.tile);
        for (int r = r0; r < r1; ++r) {
          const std::size_t row = static_cast<std::size_t>(r) * static_cast<std::size_t>(g.cols);
          for (int c = c0; c < c1; ++c) {
            const std::size_t i = row + static_cast<std::size_t>(c);
            const float x = g.x[i], y = g.y[i];
            if (!inside) {
              bool in = true;
              for (int k = 0; k < pq.n_edges && in; ++k) {
                const float* E = &pq.edge[static_cast<std::size_t>(3 * k)];
                in = E[0] * x + E[1] * y + E[2] >= 0.0f;
              }
              if (!in) continue;
            }
            const float w = pq.w[0] * x + pq.w[1] * y + pq.w[2];
            if (w > raster->w[i]) {  // NaN rays fail this test
              raster->w[i] = w;
              raster->id[i] = pq.index;
            }
          }
        }
      }
  }
}

cv::Mat Renderer::renderRadiance(const Scene& scene, const Pose& T_W_C) const {
  // Adaptive anti-aliasing: rasterise the pixel centres; a pixel whose 4-neighbours all see the same quad is shaded
  // once at its centre (the mip-mapped lookup filters the texture); a pixel on a geometric edge is split into
  // ss x ss samples, each resolved against the quads seen in its 3x3 neighbourhood and shaded on its own.
  Raster raster;
  rasterise(scene, T_W_C, grid_1_, &raster);
  const int ss = options_.supersample;
  const float inv = 1.0f / static_cast<float>(ss * ss);
  const float lod_sub = 1.0f / static_cast<float>(ss * ss);  // footprint^2 of a sub-sample relative to a pixel
  const float bias2 = static_cast<float>(std::exp2(2.0 * options_.lod_bias));
  const float background = static_cast<float>(options_.background);
  cv::Mat out(height_, width_, CV_32FC1);
  const auto& ids = raster.id;
  std::array<int, 9> cand{};
  for (int r = 0; r < height_; ++r) {
    float* dst = out.ptr<float>(r);
    for (int c = 0; c < width_; ++c) {
      const std::size_t i = static_cast<std::size_t>(r * width_ + c);
      const int id = ids[i];
      const bool edge = ss > 1 && ((c > 0 && ids[i - 1] != id) || (c + 1 < width_ && ids[i + 1] != id) ||
                                   (r > 0 && ids[i - static_cast<std::size_t>(width_)] != id) ||
                                   (r + 1 < height_ && ids[i + static_cast<std::size_t>(width_)] != id));
      if (!edge) {
        dst[c] = id < 0 ? background
                        : shadeSample(raster.shading[static_cast<std::size_t>(id)], grid_1_.x[i], grid_1_.y[i],
                                      raster.w[i], bias2);
        continue;
      }
      int n_cand = 0;
      for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if (rr < 0 || cc < 0 || rr >= height_ || cc >= width_) continue;
          const int q = ids[static_cast<std::size_t>(rr * width_ + cc)];
          if (q < 0 || std::find(cand.begin(), cand.begin() + n_cand, q) != cand.begin() + n_cand) continue;
          cand[static_cast<std::size_t>(n_cand++)] = q;
        }
      float acc = 0.0f;
      for (int dy = 0; dy < ss; ++dy)
        for (int dx = 0; dx < ss; ++dx) {
          const std::size_t j = static_cast<std::size_t>(r * ss + dy) * static_cast<std::size_t>(grid_ss_.cols) +
                                static_cast<std::size_t>(c * ss + dx);
          const float x = grid_ss_.x[j], y = grid_ss_.y[j];
          float best_w = 0.0f;
          int best = nearestHit(raster.prepared, cand.data(), n_cand, x, y, &best_w);
          if (best < 0 && !raster.visible.empty())  // a surface no neighbouring pixel centre sees (thin, oblique)
            best = nearestHit(raster.prepared, raster.visible.data(), static_cast<int>(raster.visible.size()), x, y,
                              &best_w);
          acc += best < 0 ? background
                          : shadeSample(raster.shading[static_cast<std::size_t>(best)], x, y, best_w, bias2 * lod_sub);
        }
      dst[c] = acc * inv;
    }
  }
  return out;
}

cv::Mat Renderer::renderRadianceBlurred(const Scene& scene, const std::vector<Pose>& T_W_C) const {
  if (T_W_C.empty()) throw UsageError("sim::Renderer::renderRadianceBlurred: no poses given");
  cv::Mat acc = renderRadiance(scene, T_W_C.front());
  for (std::size_t k = 1; k < T_W_C.size(); ++k) acc += renderRadiance(scene, T_W_C[k]);
  acc *= 1.0 / static_cast<double>(T_W_C.size());
  return acc;
}

cv::Mat Renderer::expose(const cv::Mat& radiance, double gain, std::uint64_t seed) const {
  if (radiance.type() != CV_32FC1 || radiance.cols != width_ || radiance.rows != height_)
    throw UsageError("sim::Renderer::expose: radiance must be CV_32FC1 of the camera's size");
  cv::Mat out(height_, width_, CV_8UC1);
  // Noise std as a function of the exposed grey level, tabulated in steps of 1/4 grey level up to 4 x 255.
  constexpr int kLutScale = 4;
  constexpr int kLutSize = 4 * 256 * kLutScale;
  std::vector<float> sigma_lut(kLutSize);
  for (int k = 0; k < kLutSize; ++k)
    sigma_lut[static_cast<std::size_t>(k)] = static_cast<float>(
        std::sqrt(options_.read_noise * options_.read_noise + options_.shot_noise * (k + 0.5) / kLutScale));
  const float g = static_cast<float>(gain);
  const std::uint64_t key = mix64(seed ^ 0x5EED5EED12345678ULL);
  for (int r = 0; r < height_; ++r) {
    const float* src = radiance.ptr<float>(r);
    std::uint8_t* dst = out.ptr<std::uint8_t>(r);
    for (int c = 0; c < width_; ++c) {
      const std::size_t i = static_cast<std::size_t>(r * width_ + c);
      const float val = src[c] * g * vignette_[i];
      const int k = std::clamp(static_cast<int>(val * kLutScale), 0, kLutSize - 1);
      const float sigma = sigma_lut[static_cast<std::size_t>(k)];
      const float noisy = val + sigma * gaussFromBits(mix64(key + i));
      dst[c] = static_cast<std::uint8_t>(std::clamp(noisy, 0.0f, 255.0f) + 0.5f);  // round half up, non-negative
    }
  }
  return out;
}

cv::Mat Renderer::render(const Scene& scene, const Pose& T_W_C, double gain, std::uint64_t seed) const {
  return expose(renderRadiance(scene, T_W_C), gain, seed);
}

cv::Mat Renderer::renderDepth(const Scene& scene, const Pose& T_W_C) const {
  Raster raster;
  rasterise(scene, T_W_C, grid_1_, &raster);
  cv::Mat out(height_, width_, CV_32FC1);
  for (int r = 0; r < height_; ++r)
    for (int c = 0; c < width_; ++c) {
      const float w = raster.w[static_cast<std::size_t>(r * width_ + c)];
      out.at<float>(r, c) = w > 0.0f ? 1.0f / w : 0.0f;
    }
  return out;
}

cv::Mat Renderer::renderQuadIds(const Scene& scene, const Pose& T_W_C) const {
  Raster raster;
  rasterise(scene, T_W_C, grid_1_, &raster);
  cv::Mat out(height_, width_, CV_32SC1);
  std::copy(raster.id.begin(), raster.id.end(), out.ptr<int>(0));
  return out;
}

}  // namespace linnet::sim
