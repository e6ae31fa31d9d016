// 4-DoF pose graph over keyframes (x, y, z, yaw), as in VINS-Mono's loop correction (Qin, Li, Shen, "VINS-Mono",
// IEEE T-RO 2018, sec. VIII): with an IMU, roll and pitch are observable and drift-free, so only the position and
// the yaw are corrected. Each keyframe keeps the odometry's roll and pitch; an edge i -> j measures the position
// of j in i's frame and the yaw difference. Odometry edges link a keyframe to its predecessors, loop edges link it
// to an older keyframe of the same place.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "linnet/core/pose.h"

namespace linnet {

/// Heading of body axis `axis` (0: x, 1: y, 2: z) of the attitude R about W's z axis, radians:
/// yawOf(rotZ(a) * R, axis) = yawOf(R, axis) + a. Defined while that axis is not vertical.
double yawOf(const Mat3& R, int axis);
/// The body axis of R closest to horizontal (a well-defined heading whatever the body's mounting: on the EuRoC MAV
/// the IMU's x axis points up, where a z-y-x yaw is degenerate).
int horizontalAxis(const Mat3& R);
/// Rotation about z by `yaw` radians.
Mat3 rotZ(double yaw);

struct PoseGraphEdge {
  std::size_t i = 0, j = 0;  // node indices
  Vec3 t_ij = Vec3::Zero();  // position of j in i's frame (the full rotation of i), m
  double yaw_ij = 0.0;       // yaw_j - yaw_i, rad
  double sigma_t = 0.01;     // m
  double sigma_yaw = 1e-3;   // rad
  bool loop = false;         // loop edges get a Huber loss
};

/// A 3D line seen from the graph's nodes (the global adjustment of the line map, LoopCloser::adjustLines): each
/// sighting's camera is held relative to its node's odometry pose (T_Wo_C, in the odometry's world), so a node's
/// correction moves its sightings with it.
struct GraphLine {
  struct Sighting {
    std::size_t node = 0;
    Pose T_Wo_C;
    Vec2 s = Vec2::Zero(), e = Vec2::Zero();  // the segment's normalised endpoints
  };
  std::array<double, 6> L{};  // Plücker coordinates [n; v] in the corrected world (LineManifold updates)
  std::vector<Sighting> sightings;
};

/// How GraphLine sightings enter a solve: endpoint-to-line distances (pixels) with a Huber loss.
struct GraphLineOptions {
  double focal_px = 460.0;   // pixels per normalised unit
  double pixel_sigma = 1.5;  // std of an endpoint distance, pixels
  double huber = 1.0;        // Huber threshold of the whitened distances
};

struct PoseGraphOptions {
  double loop_huber = 0.0;  // Huber threshold of loop edges, in sigmas (0: no robust loss)
  int max_iterations = 30;
  std::size_t first_free_node = 0;  // nodes before this one are held (0: all but node 0, which fixes the gauge)
};

class PoseGraph {
 public:
  /// Adds a node at its odometry pose (roll and pitch are kept from it); returns its index.
  std::size_t addNode(const Pose& T_W_B);
  /// The edge from the odometry poses of nodes i and j (both added).
  PoseGraphEdge odometryEdge(std::size_t i, std::size_t j, double sigma_t, double sigma_yaw) const;
  /// A loop edge from a measured relative pose T_Bi_Bj (node i older).
  PoseGraphEdge loopEdge(std::size_t i, std::size_t j, const Pose& T_Bi_Bj, double sigma_t, double sigma_yaw) const;
  void addEdge(const PoseGraphEdge& e);
  /// Removes the newest node and its edges (all edges to it are its own: it is the newest).
  void removeLastNode();

  /// Optimises every node but node 0 (held: it fixes the gauge), or only the nodes from options.first_free_node on
  /// (the older ones held), starting from the current estimates. Returns false if the solver failed (the estimates
  /// are then unchanged).
  bool optimise(const PoseGraphOptions& options);
  /// The same with lines: every node but node 0 and the lines are optimised together (the nodes' corrections move
  /// the lines' sightings). The lines' L are updated in place.
  bool optimise(const PoseGraphOptions& options, std::vector<GraphLine>* lines, const GraphLineOptions& line_options);

  std::size_t size() const { return nodes_.size(); }
  const std::vector<PoseGraphEdge>& edges() const { return edges_; }
  /// Current estimate of node k (odometry roll and pitch, optimised yaw and position).
  Pose pose(std::size_t k) const;
  const Pose& odometryPose(std::size_t k) const { return nodes_[k].odometry; }
  /// T_Wcorrected_Wodometry of node k: maps its odometry pose onto its estimate (a yaw rotation and a shift).
  Pose correction(std::size_t k) const;
  /// Sets node k's estimate (e.g. a new node initialised with the latest correction) from a pose; only its position
  /// and heading are taken.
  void setEstimate(std::size_t k, const Pose& T_W_B);
  /// Heading of an attitude with node k's reference axis, radians.
  double heading(std::size_t k, const Mat3& R) const { return yawOf(R, nodes_[k].axis); }

 private:
  struct Node {
    Pose odometry;
    int axis = 2;  // body axis whose heading is the node's yaw
    Mat3 R_tilt;   // the attitude without its heading: R = rotZ(yaw) * R_tilt
    double odometry_yaw = 0.0;  // the odometry attitude's heading (edges measure against it, never the estimate)
    double p[3];
    double yaw;    // the estimate's heading (moved by setEstimate and optimise)
  };
  std::vector<Node> nodes_;
  std::vector<PoseGraphEdge> edges_;
};

}  // namespace linnet
