// System::addStereo's two overloads: a handed-over image is kept, a shared one is copied; both give the same run.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "linnet/io/euroc_dataset.h"
#include "linnet/pipeline/dataset_runner.h"
#include "linnet/pipeline/system.h"
#include "support/shared_data.h"

namespace linnet {
namespace {

enum class Feed { kConstRef, kHandOver, kHandOverShared };

// The first `n` frames of the real snippet through one System (blocking), fed as `feed` says. With kHandOverShared
// the caller keeps a second header of each image and blanks its pixels once the call returns: the System must have
// copied them.
std::vector<FrameResult> run(const EurocDataset& data, const Config& config, std::size_t n, Feed feed) {
  System sys(config);
  std::size_t k = 0;
  const std::vector<ImuSample>& imu = data.imu();
  const Timestamp imu_start = data.frames().front().t - fromSeconds(config.estimator.init.gravity_window_s + 0.05);
  while (k < imu.size() && imu[k].t < imu_start) ++k;
  for (std::size_t i = 0; i < n && i < data.frames().size(); ++i) {
    const StereoFrameRef& f = data.frames()[i];
    for (; k < imu.size(); ++k) {
      sys.addImu(imu[k].t, imu[k].acc, imu[k].gyr);
      if (imu[k].t >= f.t) {
        ++k;
        break;
      }
    }
    cv::Mat left = EurocDataset::loadImage(f.left_path), right = EurocDataset::loadImage(f.right_path);
    if (feed == Feed::kConstRef) {
      sys.addStereo(f.t, left, right);
    } else if (feed == Feed::kHandOver) {
      sys.addStereo(f.t, std::move(left), std::move(right));
      EXPECT_TRUE(left.empty() && right.empty()) << "a handed-over image is left empty";
    } else {
      cv::Mat kept_left = left, kept_right = right;
      sys.addStereo(f.t, std::move(left), std::move(right));
      kept_left.setTo(0);
      kept_right.setTo(0);
    }
  }
  for (int extra = 0; extra < 4 && k < imu.size(); ++extra, ++k) sys.addImu(imu[k].t, imu[k].acc, imu[k].gyr);
  sys.finish();
  return sys.trajectory();
}

TEST(SystemHandOver, BothOverloadsGiveTheSameRun) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const EurocDataset data = EurocDataset::open(testing::eurocMicroDir().string());
  Config config = configForEuroc(testing::eurocMicroDir().string(), Config::eurocStereoImu());
  config.pipeline.blocking = true;
  const std::size_t n = 30;
  const std::vector<FrameResult> a = run(data, config, n, Feed::kConstRef);
  const std::vector<FrameResult> b = run(data, config, n, Feed::kHandOver);
  const std::vector<FrameResult> c = run(data, config, n, Feed::kHandOverShared);
  ASSERT_EQ(a.size(), n);
  ASSERT_EQ(b.size(), n);
  ASSERT_EQ(c.size(), n);
  int with_pose = 0;
  for (std::size_t i = 0; i < n; ++i) {
    for (const std::vector<FrameResult>* other : {&b, &c}) {
      const FrameResult& o = (*other)[i];
      ASSERT_EQ(a[i].estimate.has_pose, o.estimate.has_pose) << "frame " << i;
      EXPECT_EQ(a[i].T_W_B.matrix(), o.T_W_B.matrix()) << "frame " << i;
      EXPECT_EQ(a[i].estimate.num_points, o.estimate.num_points) << "frame " << i;
    }
    with_pose += a[i].estimate.has_pose ? 1 : 0;
  }
  EXPECT_GT(with_pose, 20);  // the run tracked: the comparison is not between empty results
}

}  // namespace
}  // namespace linnet
