// An AssetSource over bytes in memory, for fuzz targets: every file, blob and file a model
// references reads as `bytes` (so a model's .mtl or external buffer is fuzzed input too).
#pragma once

#include <string>

#include "probebake/job/asset_source.h"

namespace probebake::fuzz {

class MemoryAssetSource final : public AssetSource {
 public:
  explicit MemoryAssetSource(std::string bytes) : bytes_(std::move(bytes)) {}
  absl::StatusOr<std::string> ReadFile(const std::string&, const std::string&) const override {
    return bytes_;
  }
  absl::StatusOr<std::string> ReadBlob(const v1::Digest&, const std::string&) const override {
    return bytes_;
  }
  absl::StatusOr<std::string> ReadReferencedFile(const std::string&, const std::string&,
                                                 const std::string&) const override {
    return bytes_;
  }

 private:
  std::string bytes_;
};

}  // namespace probebake::fuzz
