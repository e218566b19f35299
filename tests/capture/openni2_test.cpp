// OpenNI2: no device and bad .oni files are reported as one-line errors, never crashes; a real Kinect
// recording (../shared/data/oni-kinect-3dj: OpenNI 1.x, recorded mirrored, colour field of view 0) plays with
// finite intrinsics, un-mirrored, depth and colour paired by time.
#include <OpenNI.h>
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "capture/error.h"
#include "capture/frame_source.h"
#include "capture/timestamp_pairing.h"

using namespace mrgi::capture;

namespace {
std::string errorOf(const std::string& uri) {
  try {
    open(uri);
  } catch (const CaptureError& e) {
    return e.what();
  }
  return "no error";
}
}  // namespace

TEST(OpenNI2, NoDeviceIsReported) {
  const std::string msg = errorOf("openni2://");
  // CI machines have no sensor; on a machine with one this test is meaningless, so accept success too.
  if (msg != "no error") {
    EXPECT_EQ(msg, "openni2://: no depth sensor connected");
  }
  EXPECT_NE(errorOf("openni2://usb/no-such-device").find("openni2://usb/no-such-device: cannot open device"),
            std::string::npos);
}

TEST(OpenNI2, MissingAndCorruptOniFiles) {
  EXPECT_EQ(errorOf("/nonexistent/take.oni"), "/nonexistent/take.oni: .oni file does not exist");
  const auto path = std::filesystem::temp_directory_path() / "mrgi_corrupt.oni";
  std::ofstream(path) << "definitely not an ONI recording";
  const std::string msg = errorOf(path.string());
  EXPECT_EQ(msg.rfind(path.string() + ": cannot open .oni file", 0), 0u) << msg;
  EXPECT_EQ(msg.find_first_of("\n\t"), std::string::npos) << msg;
  EXPECT_NE(msg.find("no ONI header"), std::string::npos) << msg;
  std::filesystem::remove(path);
}

const std::string kFixture = std::string(MRGI_SHARED_DATA) + "/oni-kinect-3dj/test.oni";

TEST(OpenNI2, TruncatedRecordingSaysWhatIsKnown) {
  const auto path = std::filesystem::temp_directory_path() / "mrgi_truncated.oni";
  {
    std::ifstream in(kFixture, std::ios::binary);
    ASSERT_TRUE(in) << kFixture;
    std::string head(100000, '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    std::ofstream(path, std::ios::binary) << head;
  }
  const std::string msg = errorOf(path.string());
  EXPECT_NE(msg.find(path.string() + ": cannot open .oni file (100000 bytes, an OpenNI 1.x recording header"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("truncated or corrupt"), std::string::npos) << msg;
  EXPECT_EQ(msg.find_first_of("\n\t"), std::string::npos) << msg;
  std::filesystem::remove(path);
}

TEST(OpenNI2, RealKinectRecordingPlaysWithFiniteIntrinsicsUnmirrored) {
  auto source = open(kFixture);
  const SourceInfo& info = source->info();
  EXPECT_EQ(info.frameCount, 12);
  // The colour stream reports a field of view of 0: it takes the depth stream's.
  EXPECT_TRUE(info.colourIntrinsics.valid());
  EXPECT_NEAR(info.colourIntrinsics.fx, info.depthIntrinsics.fx, 1e-9);
  EXPECT_NEAR(info.depthIntrinsics.fx, 575.8, 0.1);
  int frames = 0;
  cv::Mat firstColour, firstDepth;
  double last = -1;
  while (auto f = source->next()) {
    ASSERT_TRUE(f->rgbd);
    EXPECT_GT(f->timestamp, last);
    last = f->timestamp;
    if (frames++ == 0) firstColour = f->rgbd->colour, firstDepth = f->rgbd->depth;
  }
  EXPECT_EQ(frames, 12);
  // Recorded mirrored (a property playback cannot switch off): the frames come out flipped back, i.e. the
  // horizontal mirror image of what OpenNI2 itself delivers.
  ASSERT_FALSE(firstColour.empty());
  source.reset();
  openni::OpenNI::initialize();
  openni::Device device;
  ASSERT_EQ(device.open(kFixture.c_str()), openni::STATUS_OK);
  openni::VideoStream depth, colour;
  ASSERT_EQ(depth.create(device, openni::SENSOR_DEPTH), openni::STATUS_OK);
  ASSERT_EQ(colour.create(device, openni::SENSOR_COLOR), openni::STATUS_OK);
  EXPECT_TRUE(depth.getMirroringEnabled());
  EXPECT_TRUE(colour.getMirroringEnabled());
  device.getPlaybackControl()->setSpeed(-1.0f);
  depth.start();
  colour.start();
  auto read = [](openni::VideoStream& stream, openni::VideoFrameRef& frame) {
    openni::VideoStream* streams[] = {&stream};
    int ready = -1;
    return openni::OpenNI::waitForAnyStream(streams, 1, &ready, 2000) == openni::STATUS_OK &&
           stream.readFrame(&frame) == openni::STATUS_OK;
  };
  openni::VideoFrameRef d, c;
  ASSERT_TRUE(read(depth, d));
  ASSERT_TRUE(read(colour, c));
  const cv::Mat rawColour(c.getHeight(), c.getWidth(), CV_8UC3, const_cast<void*>(c.getData()), c.getStrideInBytes());
  const cv::Mat rawDepth(d.getHeight(), d.getWidth(), CV_16UC1, const_cast<void*>(d.getData()), d.getStrideInBytes());
  cv::Mat flippedColour, flippedDepth;
  cv::flip(rawColour, flippedColour, 1);
  cv::flip(rawDepth, flippedDepth, 1);
  flippedDepth.convertTo(flippedDepth, CV_32F, 1e-3);
  EXPECT_EQ(cv::norm(firstColour, flippedColour, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(firstDepth, flippedDepth, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(firstColour, rawColour, cv::NORM_L1), 0.0);  // the scene is not symmetric
  d.release();
  c.release();
  depth.stop();
  colour.stop();
  device.close();  // the player's thread before the streams, as OpenNI2Source closes it (ClosingARecording…)
  depth.destroy();
  colour.destroy();
}

TEST(OpenNI2, ClosingARecordingAtItsEndOrPartWayIsSafe) {
  // OpenNI2's file player runs on a thread of its own and is safe to tear down in only one order per state
  // (OpenNI2Source's destructor says which). A replay of the fixture crashed at its end about one run in 25
  // under load. Opened, played to its end or part-way and closed 60 times with a busy thread beside it: with
  // the streams destroyed first this crashed within a few rounds played to the end (12 of 12 runs); with the
  // device closed first, within a few rounds closed part-way (9 of 12 runs).
  std::atomic<bool> stop{false};
  std::thread load([&] {
    volatile double x = 0;
    while (!stop.load(std::memory_order_relaxed)) x = x + 1.0;
  });
  for (int round = 0; round < 60; ++round) {
    auto source = open(kFixture);
    int frames = 0;
    const int stopAt = round % 2 ? 12 : round % 12;  // every other round closes it part-way
    while (frames < stopAt && source->next()) ++frames;
    ASSERT_EQ(frames, stopAt) << round;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // the player reaches the end of the file
    source.reset();                                              // a crash here ends the test binary
  }
  stop = true;
  load.join();
}

TEST(OpenNI2, ARecordingOpensAgainOnceClosedAndNotWhileOpen) {
  // OpenNI2 gave a second opening of a file the first one's player: room and insert, which read a recording
  // while an opening of it was held, read no frame at all ("0 of 0 posed"). Opened again once closed, a
  // recording plays from its start; opened while open, it is refused in one line. (Each opening here is closed
  // the moment its last frame is read, before the player has settled: this crashed 8 runs in 60 until the
  // source waits for it.)
  for (const int stopAt : {12, 3, 12}) {
    auto source = open(kFixture);
    int frames = 0;
    while (frames < stopAt && source->next()) ++frames;
    EXPECT_EQ(frames, stopAt);
  }
  auto first = open(kFixture);
  ASSERT_TRUE(first->next());
  const std::string msg = errorOf(kFixture);
  EXPECT_NE(msg.find(kFixture + ": is already open in this process"), std::string::npos) << msg;
  int rest = 0;
  while (first->next()) ++rest;
  EXPECT_EQ(rest, 11);  // the refused opening took nothing from the first
}

TEST(TimestampPairing, EachFrameTakesTheNearestOfTheOtherStream) {
  // The second stream dropped its third frame: read-order pairing would shift every later pair.
  const std::vector<double> colour{0.010, 0.043, 0.109, 0.143};
  size_t next = 0;
  NearestInTime<int> pairs([&]() -> std::optional<std::pair<int, double>> {
    if (next >= colour.size()) return std::nullopt;
    const int i = static_cast<int>(next++);
    return std::pair{i, colour[static_cast<size_t>(i)]};
  });
  EXPECT_EQ(pairs.nearest(0.000), 0);
  EXPECT_EQ(pairs.nearest(0.033), 1);
  EXPECT_EQ(pairs.nearest(0.066), 1);  // 0.043 is nearer than 0.109
  EXPECT_EQ(pairs.nearest(0.100), 2);
  EXPECT_EQ(pairs.nearest(0.133), 3);
  EXPECT_EQ(pairs.nearest(0.500), 3);  // the last one, the stream has ended
  NearestInTime<int> empty([]() -> std::optional<std::pair<int, double>> { return std::nullopt; });
  EXPECT_FALSE(empty.nearest(0.0));
}
