// Helpers shared by the point and the point-and-line place matchers (place_matcher.cc, place_lines.cc).
#pragma once

#include <cstddef>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/loop/place_matcher.h"

namespace linnet::place_detail {

/// sigma^2 H^-1 for the information H = J^T J of n 2-row normalised image residuals whose squares sum to sum_sq,
/// sigma^2 their variance (2 n - 6 degrees of freedom). False when H is singular.
bool covarianceFromInformation(const Eigen::Matrix<double, 6, 6>& H, double sum_sq, std::size_t n,
                               Eigen::Matrix<double, 6, 6>* covariance);

/// Guided matches of a's 3D corners to b's corners around their projections by the prior T_Cb_Ca
/// (options.guided_radius_px, max_hamming, match_ratio; one 3D point per corner).
void matchGuided(const PlaceFeatures& a, const PlaceFeatures& b, const Pose& T_Cb_Ca, const PlaceMatchOptions& options,
                 std::vector<cv::Point3d>* object, std::vector<cv::Point2d>* image);

/// The match of the other direction: T_Cold_Cnew inverted, its covariance carried over.
PlaceMatch inverted(PlaceMatch r);

}  // namespace linnet::place_detail
