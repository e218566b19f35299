// The boundary's small helpers: the spelling a misspelt word most likely meant.
#include "capture/checks.h"

#include <gtest/gtest.h>

using mrgi::capture::didYouMean;
using mrgi::capture::nearestSpelling;

TEST(Spelling, TheNearestCandidateWithinAThirdOfTheWordIsSuggested) {
  const std::vector<std::string> subcommands{"replay", "record", "room", "room-lights", "reference", "live", "insert"};
  EXPECT_EQ(nearestSpelling("replya", subcommands), "replay");  // two letters swapped: one edit
  EXPECT_EQ(nearestSpelling("Replay", subcommands), "replay");  // subcommands are case-sensitive
  EXPECT_EQ(nearestSpelling("rooom", subcommands), "room");
  EXPECT_EQ(nearestSpelling("room-light", subcommands), "room-lights");
  EXPECT_EQ(nearestSpelling("xyzzy", subcommands), "");   // nothing near
  EXPECT_EQ(nearestSpelling("rm", subcommands), "");      // 2 edits from "room" is most of the word
  EXPECT_EQ(nearestSpelling("replay", subcommands), "");  // not misspelt
  const std::vector<std::string> flags{"--per-frame-mesh", "--fuse-room", "--fuse-refresh", "--frames"};
  EXPECT_EQ(nearestSpelling("--per-frame-mes", flags), "--per-frame-mesh");
  EXPECT_EQ(nearestSpelling("--fuse-rom", flags), "--fuse-room");
  EXPECT_EQ(didYouMean("--frmaes", flags), " (did you mean '--frames'?)");
  EXPECT_EQ(didYouMean("--verbose", flags), "");
  EXPECT_EQ(nearestSpelling("", flags), "");
  EXPECT_EQ(nearestSpelling(std::string(1000, 'a'), flags), "");  // long input: no quadratic work
}
