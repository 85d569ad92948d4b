// What clients are told of the server's file system: nothing. Error messages name files inside
// the data folder (which the server's log keeps in full); sent to a client, job errors, waiting
// texts and RPC statuses read "DATA/..." instead of the folder's real location.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"

namespace probebake::server {

class PathRedactor {
 public:
  PathRedactor() = default;  // changes nothing
  // The folder as given, and as an absolute and a canonical path when those differ.
  explicit PathRedactor(const std::filesystem::path& dataDir);

  // `message` with every occurrence of the data folder replaced by "DATA".
  std::string operator()(std::string_view message) const;
  // The same status with its message redacted (OK stays OK).
  absl::Status operator()(const absl::Status& status) const;

 private:
  std::vector<std::string> prefixes_;  // longest first, without a trailing separator
};

}  // namespace probebake::server
