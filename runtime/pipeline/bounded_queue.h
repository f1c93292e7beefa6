// A bounded FIFO between two pipeline stages, with the two policies a full queue can have:
// kBlock (the producer waits for room: every item is processed, as a replay wants) and
// kDropOldest (the oldest item is dropped and counted: latency stays bounded, as live cameras
// want). close() lets the consumer drain what is queued and then see the end; wake() makes
// every waiter return at once (the pipeline is stopping).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>

namespace mocap::pipeline {

enum class DropPolicy { kBlock, kDropOldest };

template <typename T>
class BoundedQueue {
 public:
  BoundedQueue(std::size_t capacity, DropPolicy policy) : capacity_(capacity), policy_(policy) {}

  // Appends `item`. kDropOldest: a full queue first loses its oldest item (*dropped += 1).
  // kBlock: waits for room. false (item not queued) once wake() was called.
  bool push(T item, std::uint64_t* dropped) {
    std::unique_lock<std::mutex> lock(mu_);
    if (policy_ == DropPolicy::kBlock) {
      cv_.wait(lock, [&] { return q_.size() < capacity_ || woken_; });
    } else if (q_.size() >= capacity_ && !woken_) {
      q_.pop_front();
      ++*dropped;
    }
    if (woken_) return false;
    q_.push_back(std::move(item));
    cv_.notify_all();
    return true;
  }

  // The oldest item, waiting up to timeout_ms; nullopt on timeout, once wake() was called, or
  // when closed and empty (drained() tells the two apart).
  std::optional<T> pop(int timeout_ms) {
    std::unique_lock<std::mutex> lock(mu_);
    cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms),
                 [&] { return !q_.empty() || closed_ || woken_; });
    if (q_.empty() || woken_) return std::nullopt;
    T item = std::move(q_.front());
    q_.pop_front();
    cv_.notify_all();
    return item;
  }

  // No more pushes: pop() returns what is queued, then nullopt with drained() true.
  void close() {
    std::lock_guard<std::mutex> lock(mu_);
    closed_ = true;
    cv_.notify_all();
  }
  bool drained() const {
    std::lock_guard<std::mutex> lock(mu_);
    return closed_ && q_.empty();
  }
  // Every waiter returns now and later calls do not wait (items queued are abandoned).
  void wake() {
    std::lock_guard<std::mutex> lock(mu_);
    woken_ = true;
    cv_.notify_all();
  }
  std::size_t size() const {
    std::lock_guard<std::mutex> lock(mu_);
    return q_.size();
  }

 private:
  const std::size_t capacity_;
  const DropPolicy policy_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<T> q_;
  bool closed_ = false;
  bool woken_ = false;
};

}  // namespace mocap::pipeline
