// Helpers of the job module's tests: temporary folders, JSON patching, error matching.
#pragma once

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace probebake::testing {

inline std::string DataDir() {
  return std::string(PROBEBAKE_TEST_DATA_DIR) + "/job";
}

inline std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A fresh folder under the test temp dir, removed with everything in it on destruction.
class TempDir {
 public:
  TempDir() {
    std::string pattern = ::testing::TempDir() + "probebake-job-XXXXXX";
    if (mkdtemp(pattern.data()) == nullptr) ADD_FAILURE() << "mkdtemp failed for " << pattern;
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::string& path() const { return path_; }
  std::string File(const std::string& name) const { return path_ + "/" + name; }
  // Writes `bytes` to <dir>/<name> and returns the full path.
  std::string Write(const std::string& name, const std::string& bytes) const {
    const std::string p = File(name);
    std::ofstream out(p, std::ios::binary);
    out.write(bytes.data(), std::streamsize(bytes.size()));
    EXPECT_TRUE(out.good()) << "cannot write " << p;
    return p;
  }

 private:
  std::string path_;
};

// Path tokens of "scene.lights[2].rect.edge1": keys and indices.
struct PathToken {
  std::string key;  // empty for an index
  int index = -1;
};

inline std::vector<PathToken> SplitPath(const std::string& path) {
  std::vector<PathToken> tokens;
  size_t i = 0;
  while (i < path.size()) {
    if (path[i] == '.') {
      ++i;
    } else if (path[i] == '[') {
      const size_t end = path.find(']', i);
      tokens.push_back({"", std::stoi(path.substr(i + 1, end - i - 1))});
      i = end + 1;
    } else {
      const size_t end = path.find_first_of(".[", i);
      tokens.push_back({path.substr(i, end == std::string::npos ? end : end - i), -1});
      i = end == std::string::npos ? path.size() : end;
    }
  }
  return tokens;
}

// `json` with the value at `path` replaced by (or set to) the JSON text `value`; an empty `value`
// removes the key (or array element). The test fails if the path does not exist.
inline std::string Patched(const std::string& json, const std::string& path,
                           const std::string& value) {
  google::protobuf::Value root;
  EXPECT_TRUE(google::protobuf::util::JsonStringToMessage(json, &root).ok()) << json;
  const std::vector<PathToken> tokens = SplitPath(path);
  google::protobuf::Value* node = &root;
  for (size_t t = 0; t + 1 < tokens.size(); ++t) {
    if (tokens[t].index >= 0) {
      EXPECT_LT(tokens[t].index, node->list_value().values_size()) << path;
      node = node->mutable_list_value()->mutable_values(tokens[t].index);
    } else {
      auto* fields = node->mutable_struct_value()->mutable_fields();
      EXPECT_TRUE(fields->contains(tokens[t].key)) << "no " << tokens[t].key << " in " << path;
      node = &(*fields)[tokens[t].key];
    }
  }
  const PathToken& last = tokens.back();
  google::protobuf::Value replacement;
  if (!value.empty()) {
    EXPECT_TRUE(google::protobuf::util::JsonStringToMessage(value, &replacement).ok()) << value;
  }
  if (last.index >= 0) {
    auto* values = node->mutable_list_value()->mutable_values();
    EXPECT_LT(last.index, values->size()) << path;
    if (value.empty()) {
      values->erase(values->begin() + last.index);
    } else {
      *values->Mutable(last.index) = replacement;
    }
  } else if (value.empty()) {
    EXPECT_EQ(node->mutable_struct_value()->mutable_fields()->erase(last.key), 1u) << path;
  } else {
    (*node->mutable_struct_value()->mutable_fields())[last.key] = replacement;
  }
  std::string out;
  EXPECT_TRUE(google::protobuf::util::MessageToJsonString(root, &out).ok());
  return out;
}

// Succeeds when `status` is INVALID_ARGUMENT and one line of its message is exactly
// "<path>: <reason...>" with `reasonPart` inside the reason.
inline ::testing::AssertionResult HasFieldError(const absl::Status& status, const std::string& path,
                                                const std::string& reasonPart = "") {
  if (status.code() != absl::StatusCode::kInvalidArgument) {
    return ::testing::AssertionFailure()
           << "expected INVALID_ARGUMENT naming " << path << ", got " << status;
  }
  std::istringstream lines{std::string(status.message())};
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind(path + ": ", 0) == 0 &&
        line.find(reasonPart, path.size() + 2) != std::string::npos)
      return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure()
         << "expected a line \"" << path << ": ..." << reasonPart << "...\", got:\n"
         << status.message();
}

}  // namespace probebake::testing
