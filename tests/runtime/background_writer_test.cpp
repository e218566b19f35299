// The replay's writer thread (runtime/background_writer.h): writes run in push order, the queue never holds
// more than its capacity (push blocks), an error reaches the frame loop once and stops later writes, and the
// destructor finishes what was queued.
#include "runtime/background_writer.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

using mrgi::runtime::BackgroundWriter;

TEST(BackgroundWriter, WritesInOrderWithABoundedQueue) {
  std::vector<int> order;
  BackgroundWriter w(3);
  for (int i = 0; i < 40; ++i)
    w.push([&order, i] {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      order.push_back(i);  // only the worker touches it until finish()
    });
  w.finish();
  ASSERT_EQ(order.size(), 40u);
  for (int i = 0; i < 40; ++i) EXPECT_EQ(order[static_cast<size_t>(i)], i);
  EXPECT_LE(w.peakQueued(), 3u);
  EXPECT_GE(w.peakQueued(), 2u);        // the loop outran the writes, so the queue filled
  EXPECT_GT(w.blockedSeconds(), 0.02);  // and push() waited for slots
  EXPECT_GT(w.busySeconds(), 0.06);
  // Usable after finish().
  w.push([&order] { order.push_back(40); });
  w.finish();
  EXPECT_EQ(order.back(), 40);
}

TEST(BackgroundWriter, AnErrorIsRethrownOnceAndStopsTheWritesAfterIt) {
  std::atomic<int> written{0};
  BackgroundWriter w(8);
  w.push([&] { ++written; });
  w.push([] { throw std::runtime_error("frame_0001.png: disk full"); });
  w.push([&] { ++written; });
  try {
    w.finish();
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "frame_0001.png: disk full");
  }
  EXPECT_EQ(written.load(), 1);
  EXPECT_THROW(w.push([&] { ++written; }), std::runtime_error);
  EXPECT_EQ(written.load(), 1);
}

TEST(BackgroundWriter, TheDestructorFinishesTheQueuedWrites) {
  std::atomic<int> written{0};
  {
    BackgroundWriter w(2);
    for (int i = 0; i < 10; ++i)
      w.push([&] {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        ++written;
      });
  }
  EXPECT_EQ(written.load(), 10);
}
