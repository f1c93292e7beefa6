// Errors as values at library boundaries. No exception escapes a library API and nothing
// calls abort() on user input: a failing parse/open returns an Error that names the thing
// (file, view, field, device) and, where there is one, the fix.
#pragma once

#include <cassert>
#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace mocap {

enum class ErrorCode {
  kInvalidArgument,  // a value given by the caller or a config is out of range
  kNotFound,         // a file, device or key does not exist
  kParse,            // a file exists but its content is malformed
  kIo,               // reading/writing failed
  kUnsupported,      // a valid request the build or hardware cannot serve
  kDevice,           // hardware or driver failure
  kDeviceLost,       // the GPU device was lost (VK_ERROR_DEVICE_LOST): re-create its context
  kConflict,         // a valid request the current state does not allow (HTTP 409)
  kInternal,         // a bug in this program
};

std::string_view to_string(ErrorCode code);

class Error {
 public:
  Error(ErrorCode code, std::string message) : code_(code), message_(std::move(message)) {}

  ErrorCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "<code>: <message>", for logs and CLI output.
  std::string to_string() const;

  // Returns a copy whose message is prefixed with `context: ` (e.g. a file name).
  Error with_context(std::string_view context) const;

 private:
  ErrorCode code_;
  std::string message_;
};

// The one way to refuse an out-of-range option or argument: Error(kInvalidArgument) whose message
// is "<stage>: <what>" ("crop plan: max_crops must be in [1, 64]"), or just <what> when the stage
// is empty (the message already names it).
Error invalid_argument(std::string_view stage, std::string_view what);

// Result<T>: a value or an Error. Accessing the wrong alternative is a programmer bug (assert).
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}      // NOLINT(google-explicit-constructor)
  Result(Error error) : v_(std::move(error)) {}  // NOLINT(google-explicit-constructor)

  bool ok() const { return std::holds_alternative<T>(v_); }
  explicit operator bool() const { return ok(); }

  T& value() & {
    assert(ok());
    return std::get<T>(v_);
  }
  const T& value() const& {
    assert(ok());
    return std::get<T>(v_);
  }
  T&& value() && {
    assert(ok());
    return std::get<T>(std::move(v_));
  }
  const Error& error() const {
    assert(!ok());
    return std::get<Error>(v_);
  }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

 private:
  std::variant<T, Error> v_;
};

// Status: success or an Error.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(Error error) : error_(std::move(error)), ok_(false) {}  // NOLINT

  static Status Ok() { return Status(); }
  bool ok() const { return ok_; }
  explicit operator bool() const { return ok_; }
  const Error& error() const {
    assert(!ok_);
    return error_;
  }

 private:
  Error error_{ErrorCode::kInternal, ""};
  bool ok_ = true;
};

}  // namespace mocap
