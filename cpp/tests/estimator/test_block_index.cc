// BlockIndex: the solver's pointer -> block table gives what a std::unordered_map gives, across growth and reuse.
#include "linnet/estimator/block_index.h"

#include <algorithm>
#include <random>
#include <unordered_map>
#include <vector>

#include <gtest/gtest.h>

namespace linnet {
namespace {

TEST(BlockIndex, AgreesWithAnUnorderedMapAcrossGrowthAndReuse) {
  std::vector<double> data(5000);
  std::mt19937 rng(7);
  BlockIndex index;
  for (int problem = 0; problem < 3; ++problem) {
    index.clear();
    EXPECT_EQ(index.size(), 0u);
    std::unordered_map<const double*, int> reference;
    // Blocks of a few doubles each, registered in a shuffled order, as a window registers poses, speeds, landmarks.
    std::vector<int> starts;
    for (int i = 0; i + 7 <= static_cast<int>(data.size()); i += 1 + static_cast<int>(rng() % 7)) starts.push_back(i);
    std::shuffle(starts.begin(), starts.end(), rng);
    starts.resize(starts.size() / (problem + 1));
    for (int k = 0; k < static_cast<int>(starts.size()); ++k) {
      const double* key = data.data() + starts[static_cast<std::size_t>(k)];
      ASSERT_TRUE(index.insert(key, k));
      reference.emplace(key, k);
      ASSERT_FALSE(index.insert(key, k + 1)) << "a second insert of the same block";
    }
    EXPECT_EQ(index.size(), reference.size());
    for (std::size_t i = 0; i < data.size(); ++i) {
      const auto it = reference.find(data.data() + i);
      EXPECT_EQ(index.find(data.data() + i), it == reference.end() ? -1 : it->second) << "offset " << i;
    }
  }
}

TEST(BlockIndex, EmptyIndexFindsNothing) {
  BlockIndex index;
  double x = 0.0;
  EXPECT_EQ(index.find(&x), -1);
  index.clear();
  EXPECT_EQ(index.find(&x), -1);
  EXPECT_TRUE(index.insert(&x, 3));
  EXPECT_EQ(index.find(&x), 3);
}

}  // namespace
}  // namespace linnet
