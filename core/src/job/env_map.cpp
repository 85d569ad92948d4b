#include "env_map.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfEnvmapAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfInputFile.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <memory>
#include <mutex>
#include <stdexcept>

#include "probebake/base/status.h"

#include "stb_image_decode.h"
#include "text.h"

namespace probebake::job_internal {
namespace {

// An Imf::IStream over bytes in memory (OpenEXR reads from files or from an IStream).
class MemoryIStream final : public Imf::IStream {
 public:
  explicit MemoryIStream(std::string_view bytes) : Imf::IStream("<memory>"), bytes_(bytes) {}

  bool read(char c[], int n) override {
    if (n < 0 || uint64_t(n) > bytes_.size() - std::min<uint64_t>(position_, bytes_.size())) {
      throw std::runtime_error("unexpected end of file");
    }
    std::memcpy(c, bytes_.data() + position_, size_t(n));
    position_ += uint64_t(n);
    return position_ < bytes_.size();
  }
  uint64_t tellg() override { return position_; }
  void seekg(uint64_t position) override { position_ = position; }

 private:
  std::string_view bytes_;
  uint64_t position_ = 0;
};

// The largest tile side an OpenEXR environment may declare (tiles are buffered whole).
constexpr int kMaxTileSide = 4096;

bool IsOpenExr(std::string_view bytes) {
  return bytes.size() >= 4 && bytes.substr(0, 4) == std::string_view("\x76\x2f\x31\x01", 4);
}

// Radiance files start with "#?" and a program name ("#?RADIANCE", "#?RGBE").
bool IsRadianceHdr(std::string_view bytes) {
  return bytes.size() >= 2 && bytes.substr(0, 2) == "#?";
}

// Bytes a channel list takes when read by its contents, as OpenEXR reads it: entries of a
// zero-terminated name and 16 bytes (pixel type, pLinear, 3 reserved, x and y sampling), ended by
// an empty name. npos when it runs past `value`.
size_t ChannelListBytes(std::string_view value) {
  size_t at = 0;
  for (;;) {
    const size_t end = value.find('\0', at);
    if (end == std::string_view::npos) return std::string_view::npos;
    if (end == at) return at + 1;  // the empty name ending the list
    at = end + 1 + 16;
    if (at > value.size()) return std::string_view::npos;
  }
}

// Bytes a preview image takes by its contents: width and height (uint32), then 4 bytes a pixel.
uint64_t PreviewBytes(std::string_view value) {
  if (value.size() < 8) return UINT64_MAX;
  const auto u32 = [&](size_t i) {
    return uint64_t(uint8_t(value[i])) | uint64_t(uint8_t(value[i + 1])) << 8 |
           uint64_t(uint8_t(value[i + 2])) << 16 | uint64_t(uint8_t(value[i + 3])) << 24;
  };
  return 8 + 4 * u32(0) * u32(4);
}

// OpenEXR allocates each header attribute at the size the file declares before reading it, so a
// damaged file can make it allocate gigabytes: every attribute's size is checked against the
// bytes left first. "" when the headers fit, else what does not.
std::string ExrHeaderProblem(std::string_view bytes) {
  constexpr uint32_t kMultiPart = 0x1000;
  if (bytes.size() < 8) return "it ends inside its version field";
  size_t at = 8;  // magic and version
  const uint32_t version = uint32_t(uint8_t(bytes[4])) | uint32_t(uint8_t(bytes[5])) << 8 |
                           uint32_t(uint8_t(bytes[6])) << 16 | uint32_t(uint8_t(bytes[7])) << 24;
  const auto zeroTerminated = [&](std::string* out) {
    const size_t end = bytes.find('\0', at);
    if (end == std::string_view::npos || end - at > 255) return false;
    *out = std::string(bytes.substr(at, end - at));
    at = end + 1;
    return true;
  };
  for (;;) {
    for (;;) {
      std::string name, type;
      if (!zeroTerminated(&name)) return "its header is cut short or has a name over 255 bytes";
      if (name.empty()) break;  // the end of this header
      if (!zeroTerminated(&type) || bytes.size() - at < 4)
        return "its header is cut short at attribute \"" + name + "\"";
      const int32_t size =
          int32_t(uint32_t(uint8_t(bytes[at])) | uint32_t(uint8_t(bytes[at + 1])) << 8 |
                  uint32_t(uint8_t(bytes[at + 2])) << 16 | uint32_t(uint8_t(bytes[at + 3])) << 24);
      at += 4;
      if (size < 0 || uint64_t(size) > bytes.size() - at) {
        return "its header attribute \"" + name + "\" declares " + std::to_string(size) +
               " bytes; " + std::to_string(bytes.size() - at) + " are left";
      }
      // OpenEXR reads these two by their contents, not by the declared size (a preview's pixels
      // are allocated from its width and height): contents and size must agree, or the reader
      // parts from this walk and sizes its buffers from bytes that are not sizes.
      const std::string_view value = bytes.substr(at, size_t(size));
      if ((type == "chlist" && ChannelListBytes(value) != size_t(size)) ||
          (type == "preview" && PreviewBytes(value) != uint64_t(size))) {
        return "its header attribute \"" + name + "\" (" + type +
               ") does not hold what its size of " + std::to_string(size) + " bytes declares";
      }
      at += size_t(size);
    }
    // A single-part file has one header; a multi-part file lists them until an empty one.
    if (!(version & kMultiPart)) return "";
    if (at >= bytes.size()) return "its header list is cut short";
    if (bytes[at] == '\0') return "";
  }
}

// stb_image's Radiance decoder reads a byte past the end as 0, and a run-length scanline whose
// data ends early then reads zero-length runs for ever (found by env_image_fuzz: a 143-byte file
// never returned). The scanlines are walked first: "" when every one fits in the file (or the
// header is one stb_image refuses itself), else what is cut short.
std::string RadianceDataProblem(std::string_view bytes) {
  const size_t headerEnd = bytes.find("\n\n");
  if (headerEnd == std::string_view::npos) return "";
  const size_t lineEnd = bytes.find('\n', headerEnd + 2);
  if (lineEnd == std::string_view::npos) return "";
  long height = 0, width = 0;
  const std::string resolution(bytes.substr(headerEnd + 2, lineEnd - headerEnd - 2));
  if (std::sscanf(resolution.c_str(), "-Y %ld +X %ld", &height, &width) != 2 || height < 1 ||
      width < 1 || height > (1 << 24) || width > (1 << 24)) {
    return "";  // stb_image names the fault
  }
  size_t at = lineEnd + 1;
  const auto left = [&] { return bytes.size() - at; };
  const std::string cut = "its pixel data is cut short";
  const uint64_t flatBytes = 4 * uint64_t(width) * uint64_t(height);
  // Flat (not run-length) pixels: 4 bytes each, from here to the end of the image.
  if (width < 8 || width >= 32768) return flatBytes <= left() ? "" : cut;
  for (long row = 0; row < height; ++row) {
    if (left() < 4) return cut;
    const auto c1 = uint8_t(bytes[at]), c2 = uint8_t(bytes[at + 1]), hi = uint8_t(bytes[at + 2]);
    if (c1 != 2 || c2 != 2 || (hi & 0x80)) {
      // stb_image reads the whole image flat from here, these 4 bytes its first pixel.
      return flatBytes <= left() ? "" : cut;
    }
    if (((long(hi) << 8) | uint8_t(bytes[at + 3])) != width) return "";  // stb_image refuses it
    at += 4;
    for (int channel = 0; channel < 4; ++channel) {
      for (long x = 0; x < width;) {
        if (left() < 1) return cut;
        long count = uint8_t(bytes[at++]);
        if (count > 128) {  // a run: one value
          if (left() < 1) return cut;
          ++at;
          count -= 128;
        } else {                             // literal values
          if (count > width - x) return "";  // stb_image refuses it
          if (uint64_t(count) > left()) return cut;
          at += size_t(count);
        }
        if (count > width - x) return "";
        x += count;
      }
    }
  }
  return "";
}

absl::Status CheckSize(int64_t width, int64_t height, int64_t maxPixels, const std::string& what,
                       const std::string& fieldPath) {
  if (width < 1 || height < 1) return FieldError(fieldPath, what + " has no pixels");
  if (maxPixels > 0 && width * height > maxPixels) {
    return FieldError(fieldPath, what + " has " + Num(width) + " x " + Num(height) +
                                     " pixels, above the limit of " + Num(maxPixels));
  }
  return absl::OkStatus();
}

absl::Status DecodeRadianceHdr(std::string_view bytes, const std::string& what,
                               const std::string& fieldPath, int64_t maxPixels,
                               EnvironmentMap* map) {
  StbImageInfo info;
  std::string error;
  if (!StbImageHeader(bytes, &info, &error) || !info.radiance) {
    return FieldError(fieldPath, "cannot read " + what + " as Radiance HDR: " +
                                     (error.empty() ? "not a Radiance HDR file" : error));
  }
  const int width = info.width, height = info.height;
  PB_RETURN_IF_ERROR(CheckSize(width, height, maxPixels, what, fieldPath));
  if (const std::string problem = RadianceDataProblem(bytes); !problem.empty())
    return FieldError(fieldPath, "cannot read " + what + " as Radiance HDR: " + problem);
  std::vector<float> rgb;
  if (!StbDecodeRadiance(bytes, &rgb, &error))
    return FieldError(fieldPath, "cannot read " + what + " as Radiance HDR: " + error);
  map->width = width;
  map->height = height;
  map->rgb = std::move(rgb);
  return absl::OkStatus();
}

absl::Status DecodeOpenExr(std::string_view bytes, const std::string& what,
                           const std::string& fieldPath, int64_t maxPixels, EnvironmentMap* out,
                           bool* cubeTagged) {
  EnvironmentMap& map = *out;
  try {
    if (const std::string problem = ExrHeaderProblem(bytes); !problem.empty())
      return FieldError(fieldPath, "cannot read " + what + " as OpenEXR: " + problem);
    {
      // The header alone first: opening the file sizes OpenEXR's buffers by the data window (and
      // tiles), which a damaged file can declare as large as it likes.
      static std::once_flag tiles;
      std::call_once(tiles, [] { Imf::Header::setMaxTileSize(kMaxTileSide, kMaxTileSide); });
      MemoryIStream headerStream(bytes);
      headerStream.seekg(4);
      char versionBytes[4];
      headerStream.read(versionBytes, 4);
      int version =
          int(uint32_t(uint8_t(versionBytes[0])) | uint32_t(uint8_t(versionBytes[1])) << 8 |
              uint32_t(uint8_t(versionBytes[2])) << 16 | uint32_t(uint8_t(versionBytes[3])) << 24);
      Imf::Header declared;
      declared.readFrom(headerStream, version);
      const Imath::Box2i window = declared.dataWindow();
      PB_RETURN_IF_ERROR(CheckSize(int64_t(window.max.x) - window.min.x + 1,
                                   int64_t(window.max.y) - window.min.y + 1, maxPixels, what,
                                   fieldPath));
    }
    MemoryIStream stream(bytes);
    Imf::InputFile file(stream);
    const Imf::Header& header = file.header();
    const Imath::Box2i window = header.dataWindow();
    const int64_t width = int64_t(window.max.x) - window.min.x + 1;
    const int64_t height = int64_t(window.max.y) - window.min.y + 1;
    if (width < 1 || height < 1) return FieldError(fieldPath, what + " has an empty data window");
    PB_RETURN_IF_ERROR(CheckSize(width, height, maxPixels, what, fieldPath));
    const auto* envmap = header.findTypedAttribute<Imf::EnvmapAttribute>("envmap");
    *cubeTagged = envmap != nullptr && envmap->value() == Imf::ENVMAP_CUBE;

    const Imf::ChannelList& channels = header.channels();
    const bool rgb =
        channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B");
    const bool grey = !rgb && channels.findChannel("Y") != nullptr;
    if (!rgb && !grey) {
      std::string names;
      for (auto it = channels.begin(); it != channels.end(); ++it)
        names += std::string(names.empty() ? "" : ", ") + it.name();
      return FieldError(fieldPath, what + " has no R, G, B or Y channels (found: " + names + ")");
    }
    if (grey && (channels.findChannel("RY") || channels.findChannel("BY"))) {
      return FieldError(fieldPath, what + " is a luminance/chroma image; save it as RGB");
    }
    for (const char* channel : {"R", "G", "B", "Y"}) {
      const Imf::Channel* c = channels.findChannel(channel);
      if (c != nullptr && (c->xSampling != 1 || c->ySampling != 1)) {
        return FieldError(fieldPath, what + " has a subsampled channel " + channel);
      }
    }

    map.width = int(width);
    map.height = int(height);
    map.dataWindowMinX = window.min.x;
    map.dataWindowMinY = window.min.y;
    map.rgb.assign(size_t(width * height * 3), 0.0f);
    // FLOAT slices, never half: a sun is brighter than half's largest value (65504).
    Imf::FrameBuffer frame;
    const size_t xStride = 3 * sizeof(float), yStride = xStride * size_t(width);
    if (rgb) {
      for (int c = 0; c < 3; ++c) {
        frame.insert(c == 0   ? "R"
                     : c == 1 ? "G"
                              : "B",
                     Imf::Slice::Make(Imf::FLOAT, map.rgb.data() + c, window, xStride, yStride));
      }
    } else {
      frame.insert("Y", Imf::Slice::Make(Imf::FLOAT, map.rgb.data(), window, xStride, yStride));
    }
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    if (grey) {
      for (size_t p = 0; p < size_t(width * height); ++p) {
        map.rgb[3 * p + 1] = map.rgb[3 * p + 2] = map.rgb[3 * p];
      }
    }
  } catch (const std::exception& e) {
    return FieldError(fieldPath, "cannot read " + what + " as OpenEXR: " + e.what());
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<EnvironmentImage> DecodeEnvironmentImage(std::string_view bytes,
                                                        const std::string& name,
                                                        const std::string& fieldPath,
                                                        int64_t maxPixels) {
  const std::string what = Quoted(name);
  EnvironmentImage image;
  EnvironmentMap& map = image.pixels;
  if (IsOpenExr(bytes)) {
    PB_RETURN_IF_ERROR(DecodeOpenExr(bytes, what, fieldPath, maxPixels, &map, &image.cubeTagged));
  } else if (IsRadianceHdr(bytes)) {
    PB_RETURN_IF_ERROR(DecodeRadianceHdr(bytes, what, fieldPath, maxPixels, &map));
  } else {
    return FieldError(fieldPath, what + " is neither an OpenEXR nor a Radiance HDR file");
  }

  for (size_t k = 0; k < map.rgb.size(); ++k) {
    const float v = map.rgb[k];
    if (!std::isfinite(v) || v < 0) {
      const int64_t pixel = int64_t(k / 3);
      return FieldError(fieldPath, what + " pixel (" + Num(map.dataWindowMinX + pixel % map.width) +
                                       ", " + Num(map.dataWindowMinY + pixel / map.width) +
                                       ") has " +
                                       (std::isfinite(v) ? "a negative" : "a non-finite") +
                                       " value (" + Num(double(v)) + ")");
    }
  }
  return image;
}

}  // namespace probebake::job_internal
