// BoundedQueue: the two full-queue policies, close/drain and wake.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "runtime/pipeline/bounded_queue.h"

namespace mocap::pipeline {
namespace {

TEST(BoundedQueue, DropOldestKeepsTheNewestAndCountsTheRest) {
  BoundedQueue<int> q(2, DropPolicy::kDropOldest);
  std::uint64_t dropped = 0;
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(q.push(i, &dropped));
  EXPECT_EQ(dropped, 3u);
  EXPECT_EQ(q.pop(0), 3);
  EXPECT_EQ(q.pop(0), 4);
  EXPECT_FALSE(q.pop(0));
}

TEST(BoundedQueue, BlockWaitsForRoomAndLosesNothing) {
  BoundedQueue<int> q(1, DropPolicy::kBlock);
  std::uint64_t dropped = 0;
  std::atomic<int> pushed{0};
  std::thread producer([&] {
    for (int i = 0; i < 20; ++i) {
      if (!q.push(i, &dropped)) return;
      ++pushed;
    }
    q.close();
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_LE(pushed.load(), 2);  // one queued, the next one waiting for room
  std::vector<int> got;
  while (true) {
    auto v = q.pop(1000);
    if (!v) break;
    got.push_back(*v);
  }
  producer.join();
  EXPECT_TRUE(q.drained());
  EXPECT_EQ(dropped, 0u);
  ASSERT_EQ(got.size(), 20u);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(got[static_cast<std::size_t>(i)], i);
}

TEST(BoundedQueue, CloseDrainsThenEnds) {
  BoundedQueue<int> q(4, DropPolicy::kBlock);
  std::uint64_t dropped = 0;
  q.push(1, &dropped);
  q.close();
  EXPECT_FALSE(q.drained());
  EXPECT_EQ(q.pop(0), 1);
  EXPECT_FALSE(q.pop(1000));  // returns at once: closed and empty
  EXPECT_TRUE(q.drained());
}

TEST(BoundedQueue, WakeReleasesABlockedProducerAndAWaitingConsumer) {
  BoundedQueue<int> full(1, DropPolicy::kBlock);
  BoundedQueue<int> empty(1, DropPolicy::kBlock);
  std::uint64_t dropped = 0;
  full.push(0, &dropped);
  std::atomic<bool> producer_back{false}, consumer_back{false};
  std::thread producer([&] {
    EXPECT_FALSE(full.push(1, &dropped));
    producer_back = true;
  });
  std::thread consumer([&] {
    EXPECT_FALSE(empty.pop(60000));
    consumer_back = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(producer_back.load());
  EXPECT_FALSE(consumer_back.load());
  full.wake();
  empty.wake();
  producer.join();
  consumer.join();
  EXPECT_TRUE(producer_back.load());
  EXPECT_TRUE(consumer_back.load());
}

}  // namespace
}  // namespace mocap::pipeline
