// What a long command says of its progress: a bar on a terminal, a line per 10 % elsewhere, both with the time
// spent and, once the rate is known, the time left.
#include <gtest/gtest.h>

#include "runtime/output.h"

using mrgi::runtime::progressText;

TEST(Progress, TheLineAndTheBarSayTheTimeSpentAndLeft) {
  EXPECT_EQ(progressText("room", 0.4, 12.3, 18.0, false), "room: 40 % (12 s, about 18 s left)");
  EXPECT_EQ(progressText("room", 1.0, 30.0, 0.0, false), "room: 100 % (30 s)");
  EXPECT_EQ(progressText("replay", 0.1, 2.0, -1.0, false), "replay: 10 % (2 s)");  // no rate yet
  EXPECT_EQ(progressText("room", 0.5, 10.0, 10.0, true),
            "room [####################....................]  50%  10 s, about 10 s left");
  // Out-of-range and non-finite input stays readable.
  EXPECT_EQ(progressText("x", 7.0, 1.0, 1.0, false), "x: 100 % (1 s)");
  EXPECT_EQ(progressText("x", std::nan(""), 1.0, std::nan(""), false), "x: 0 % (1 s)");
}
