#include "runtime/core/error.h"

namespace mocap {

std::string_view to_string(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidArgument:
      return "invalid argument";
    case ErrorCode::kNotFound:
      return "not found";
    case ErrorCode::kParse:
      return "parse error";
    case ErrorCode::kIo:
      return "I/O error";
    case ErrorCode::kUnsupported:
      return "unsupported";
    case ErrorCode::kDevice:
      return "device error";
    case ErrorCode::kDeviceLost:
      return "device lost";
    case ErrorCode::kConflict:
      return "conflict";
    case ErrorCode::kInternal:
      return "internal error";
  }
  return "unknown error";
}

std::string Error::to_string() const {
  std::string s(mocap::to_string(code_));
  s += ": ";
  s += message_;
  return s;
}

Error Error::with_context(std::string_view context) const {
  std::string m(context);
  m += ": ";
  m += message_;
  return Error(code_, std::move(m));
}

Error invalid_argument(std::string_view stage, std::string_view what) {
  if (stage.empty()) return Error(ErrorCode::kInvalidArgument, std::string(what));
  std::string m(stage);
  m += ": ";
  m += what;
  return Error(ErrorCode::kInvalidArgument, std::move(m));
}

}  // namespace mocap
