#include "runtime/eval/id_switches.h"

#include <gtest/gtest.h>

namespace mocap::eval {
namespace {

// One person walking along x at 1 cm a frame, under `id` for frames [from, to].
void walk(TrackBook& book, int id, std::int64_t from, std::int64_t to) {
  for (std::int64_t f = from; f <= to; ++f) book.add(f, id, {0.01 * static_cast<double>(f), 0, 1});
}

TEST(IdSwitches, ANewIdWhereALongTrackEndedIsASwitch) {
  TrackBook book;
  walk(book, 1, 0, 40);
  walk(book, 2, 43, 100);  // 3 frames later, 3 cm on
  const auto s = book.switches(100);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].from_id, 1);
  EXPECT_EQ(s[0].to_id, 2);
  EXPECT_EQ(s[0].frame, 43);
  EXPECT_NEAR(s[0].distance_m, 0.03, 1e-9);
  // Overlapping (a duplicate that outlived the first): counted too, within the gap.
  TrackBook overlap;
  walk(overlap, 1, 0, 40);
  walk(overlap, 2, 30, 100);
  EXPECT_EQ(overlap.switches(100).size(), 1u);
}

TEST(IdSwitches, WhatIsNotASwitch) {
  TrackBook flicker;  // the old track too short to count
  walk(flicker, 1, 0, kLongTrackFrames - 2);
  walk(flicker, 2, kLongTrackFrames, 60);
  EXPECT_TRUE(flicker.switches(60).empty());

  TrackBook late;  // the new id comes after the gap
  walk(late, 1, 0, 40);
  walk(late, 2, 41 + kSwitchMaxGapFrames, 100);
  EXPECT_TRUE(late.switches(100).empty());

  TrackBook far;  // another person, far from where the first was last seen
  walk(far, 1, 0, 40);
  for (std::int64_t f = 42; f <= 100; ++f) far.add(f, 2, {5, 5, 1});
  EXPECT_TRUE(far.switches(100).empty());

  TrackBook together;  // two people seen to the end: nobody ended
  walk(together, 1, 0, 100);
  for (std::int64_t f = 5; f <= 100; ++f)
    together.add(f, 2, {0.01 * static_cast<double>(f), 0.3, 1});
  EXPECT_TRUE(together.switches(100).empty());

  TrackBook back;  // the same id back after a gap is one track, not a switch
  walk(back, 1, 0, 40);
  walk(back, 1, 60, 100);
  EXPECT_TRUE(back.switches(100).empty());
  EXPECT_EQ(back.tracks().at(1).frames, 82);
}

}  // namespace
}  // namespace mocap::eval
