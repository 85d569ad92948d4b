#include "errors.h"

namespace probebake::job_internal {

void ErrorList::Add(std::string_view path, std::string_view reason) {
  if (lines_.size() >= kMaxLines) {
    ++dropped_;
    return;
  }
  std::string line(path);
  if (!line.empty()) line += ": ";
  line += reason;
  lines_.push_back(std::move(line));
}

absl::Status ErrorList::ToStatus() const {
  if (lines_.empty()) return absl::OkStatus();
  std::string message;
  for (const std::string& line : lines_) {
    if (!message.empty()) message += '\n';
    message += line;
  }
  if (dropped_ > 0) message += "\n... and " + std::to_string(dropped_) + " more errors";
  return absl::InvalidArgumentError(message);
}

absl::Status PrefixLines(const absl::Status& status, std::string_view prefix) {
  if (status.ok()) return status;
  const std::string message(status.message());
  std::string out;
  size_t start = 0;
  while (true) {
    const size_t end = message.find('\n', start);
    out += prefix;
    out += ": ";
    out += message.substr(start, end == std::string::npos ? std::string::npos : end - start);
    if (end == std::string::npos) break;
    out += '\n';
    start = end + 1;
  }
  return absl::Status(status.code(), out);
}

}  // namespace probebake::job_internal
