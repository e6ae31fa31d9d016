#include "linnet/pipeline/config.h"

#include <gtest/gtest.h>

#include "linnet/core/error.h"
#include "linnet/pipeline/dataset_runner.h"
#include "support/shared_data.h"

namespace linnet {
namespace {

TEST(Config, YamlRoundTripIsExact) {
  // The extrinsics pass through a quaternion once (re-orthonormalisation); from then on save -> load is exact.
  const std::string text = Config::fromYaml(Config::eurocStereoImu().toYaml(), "first").toYaml();
  const Config d = Config::fromYaml(text, "test");
  EXPECT_EQ(d.toYaml(), text);
  EXPECT_LT((d.cam0.T_B_C.matrix() - Config::eurocStereoImu().cam0.T_B_C.matrix()).norm(), 1e-12);
}

TEST(Config, ErrorsNameTheKey) {
  try {
    Config::fromYaml("estimator:\n  window_size: 0\n", "cfg.yaml");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("estimator.window_size"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Config::fromYaml("points:\n  nope: 1\n"), ConfigError);
}

TEST(Config, TakesTheCalibrationOfAEurocFolder) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const Config c = configForEuroc(testing::eurocMicroDir().string(), Config::eurocStereoImu());
  EXPECT_TRUE(c.stereo);
  EXPECT_NEAR(c.cam1.intrinsics[0], 457.587, 1e-9);
  EXPECT_NEAR(c.imu.gyr_noise_density, 1.6968e-4, 1e-12);
}

}  // namespace
}  // namespace linnet
