// SPDX-License-Identifier: BSD-3-Clause
// Copyright (c) 2026, stereo_pf developers
// A one-place mailbox between the thread that receives frames and the thread that tracks them: the receiver
// never waits, the tracker always gets the newest frame, and every frame that was replaced before the tracker
// took it is counted. This is the tracker's drop policy under overload (keep the newest, count the rest).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <utility>

namespace stereo_pf
{
template <class T>
class LatestSlot
{
public:
  /// Put `item` in the slot. Returns true when it replaced an item nobody had taken yet (that one is dropped).
  bool put(T item)
  {
    bool replaced = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (closed_)
        return false;
      replaced = item_.has_value();
      item_ = std::move(item);
      ++put_;
      replaced_ += replaced ? 1 : 0;
    }
    ready_.notify_one();
    return replaced;
  }

  /// Wait for an item and move it into `item`; false (and `item` untouched) once close() was called.
  bool take(T& item)
  {
    std::unique_lock<std::mutex> lock(mutex_);
    ready_.wait(lock, [this] { return closed_ || item_.has_value(); });
    if (closed_)
      return false;
    item = std::move(*item_);
    item_.reset();
    return true;
  }

  /// Wake every take() for good and drop what is waiting; later put()s are ignored.
  void close()
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
      item_.reset();
    }
    ready_.notify_all();
  }

  /// Items put so far, and of them those replaced before being taken.
  uint64_t putCount() const
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return put_;
  }
  uint64_t replacedCount() const
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return replaced_;
  }

private:
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::optional<T> item_;
  bool closed_ = false;
  uint64_t put_ = 0, replaced_ = 0;
};

}  // namespace stereo_pf
