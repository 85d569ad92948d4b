// Collecting "<field path>: <reason>" lines into one status (private to core/src/job).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"

namespace probebake::job_internal {

class ErrorList {
 public:
  // Lines kept; later errors are only counted, so a huge broken job gives a readable message.
  static constexpr size_t kMaxLines = 50;

  // Adds "<path>: <reason>", or just `reason` when `path` is empty (the job as a whole).
  void Add(std::string_view path, std::string_view reason);
  bool ok() const { return lines_.empty(); }
  // OK, or INVALID_ARGUMENT with the lines joined by "\n" (first error first) and, past kMaxLines,
  // a last line "... and N more errors".
  absl::Status ToStatus() const;

 private:
  std::vector<std::string> lines_;
  size_t dropped_ = 0;
};

// Why a light above kMaxEmitted (limits.h) is refused, after "<value> is more than 1e30, ".
inline constexpr char kBeyondVolumeFloats[] =
    "which the volume's 32-bit floats cannot hold once projected; use a smaller light unit";

// `status` with "<prefix>: " put before every line of its message; the code is kept.
absl::Status PrefixLines(const absl::Status& status, std::string_view prefix);

}  // namespace probebake::job_internal
