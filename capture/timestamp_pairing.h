#pragma once
/// Pairs each frame of one stream with the frame of another stream nearest in time, reading the second
/// stream ahead as far as needed (one frame of look-ahead). Used where two streams of a recording are read
/// independently (OpenNI2 playback of depth and colour), so that a dropped or extra frame in one stream
/// does not shift every later pair.
#include <cmath>
#include <functional>
#include <optional>

namespace mrgi::capture {

template <class Item>
class NearestInTime {
 public:
  /// read: the next item of the second stream and its timestamp (seconds), nullopt at its end.
  using Reader = std::function<std::optional<std::pair<Item, double>>()>;
  explicit NearestInTime(Reader read) : read_(std::move(read)) {}

  /// The item nearest to time t (items of the second stream are consumed up to it; a later call with a
  /// later t never returns an earlier item). nullopt when the second stream is empty.
  std::optional<Item> nearest(double t) {
    if (!current_) current_ = read_();
    if (!current_) return std::nullopt;
    while (true) {
      if (!next_) next_ = read_();
      if (!next_ || std::abs(next_->second - t) > std::abs(current_->second - t)) break;
      current_ = std::move(next_);
      next_.reset();
    }
    return current_->first;
  }

 private:
  Reader read_;
  std::optional<std::pair<Item, double>> current_, next_;
};

}  // namespace mrgi::capture
