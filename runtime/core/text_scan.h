// Whole-file reading and writing of text, and a fast tokenizer for whitespace-separated numbers:
// the dataset loaders (runtime/io), the calibration's reports, take files and the tools use it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "runtime/core/error.h"

namespace mocap {

// Reads a whole file into memory. kNotFound when it does not exist, kIo when it cannot be
// opened or read, kInvalidArgument when it is larger than `max_bytes`.
Result<std::string> read_text_file(const std::filesystem::path& path,
                                   std::uintmax_t max_bytes = std::uintmax_t{1} << 30);

// Writes `text` to `path` (truncating). kIo names the path on failure.
Status write_text_file(const std::filesystem::path& path, std::string_view text);

// Outcome of reading one number.
enum class ScanStatus {
  kOk,
  kEnd,         // no token left
  kNotNumber,   // the token is not (entirely) a number of the requested kind
  kOutOfRange,  // a number, but it does not fit the type
  kNonFinite,   // nan / inf
};

// A forward tokenizer over whitespace-separated ASCII text (space, \t, \n, \r, \v, \f). Any
// other byte, NUL included, belongs to a token. Tracks the 1-based line of the last token.
// Never reads outside the given view.
class TextScanner {
 public:
  explicit TextScanner(std::string_view text) : p_(text.data()), end_(text.data() + text.size()) {}

  // Reads the next token as an integer (decimal, optional '-').
  ScanStatus next_int(std::int64_t& value);
  // Reads the next token as a finite float / double (fixed or scientific notation).
  ScanStatus next_float(float& value);
  ScanStatus next_double(double& value);

  // True when only whitespace is left.
  bool at_end();

  // Upper bound on the number of tokens left (each needs a byte and a separator): used to
  // refuse counts that the remaining input cannot possibly hold before allocating for them.
  std::size_t max_tokens_left() const { return (static_cast<std::size_t>(end_ - p_) + 1) / 2; }

  // Line (1-based) of the token most recently read or attempted.
  int line() const { return token_line_; }
  // The token most recently read or attempted, quoted and made printable (at most ~24
  // characters), or "end of file" when there was none: for error messages.
  std::string last_token_for_message() const;

 private:
  // Skips whitespace; false at end of input.
  bool skip_space();
  const char* token_end(const char* from) const;

  const char* p_;
  const char* end_;
  const char* token_ = nullptr;  // start of the last token (nullptr: end of file)
  int line_ = 1;                 // line of p_
  int token_line_ = 1;
};

// A readable reason for a failed read, quoting the offending token.
std::string describe(ScanStatus status, const TextScanner& scan);

// `bytes` for a message: printable ASCII as it is, every other byte as \xNN.
std::string printable_bytes(std::string_view bytes);

}  // namespace mocap
