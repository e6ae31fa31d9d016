#include "linnet/pipeline/bounded_queue.h"

#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace linnet {
namespace {

TEST(BoundedQueue, FifoOrderAndEndOfStream) {
  BoundedQueue<int> q(3);
  EXPECT_TRUE(q.push(1));
  EXPECT_TRUE(q.push(2));
  q.close();
  EXPECT_FALSE(q.push(3));
  EXPECT_EQ(q.pop().value(), 1);
  EXPECT_EQ(q.pop().value(), 2);
  EXPECT_FALSE(q.pop().has_value());
}

TEST(BoundedQueue, TryPushDropsWhenFull) {
  BoundedQueue<int> q(2);
  EXPECT_TRUE(q.tryPush(1));
  EXPECT_TRUE(q.tryPush(2));
  EXPECT_FALSE(q.tryPush(3));
  EXPECT_EQ(q.size(), 2u);
}

TEST(BoundedQueue, BlockingProducerConsumerKeepsEverythingInOrder) {
  BoundedQueue<int> q(4);
  std::vector<int> got;
  std::thread consumer([&] {
    while (auto v = q.pop()) got.push_back(*v);
  });
  for (int i = 0; i < 1000; ++i) ASSERT_TRUE(q.push(i));
  q.close();
  consumer.join();
  ASSERT_EQ(got.size(), 1000u);
  for (int i = 0; i < 1000; ++i) EXPECT_EQ(got[i], i);
}

TEST(BoundedQueue, CloseWakesABlockedProducer) {
  BoundedQueue<int> q(1);
  ASSERT_TRUE(q.push(0));
  bool result = true;
  std::thread producer([&] { result = q.push(1); });
  q.close();
  producer.join();
  EXPECT_FALSE(result);
}

}  // namespace
}  // namespace linnet
