#include "mesh_import.h"

#include <assimp/BaseImporter.h>
#include <assimp/GltfMaterial.h>
#include <assimp/MemoryIOWrapper.h>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include <assimp/IOSystem.hpp>
#include <assimp/Importer.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <exception>
#include <map>
#include <memory>
#include <set>
#include <utility>

#include "assimp_warnings.h"
#include "mesh_file_check.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/limits.h"
#include "stb_image_decode.h"
#include "text.h"

namespace probebake::job_internal {
namespace {

// An Embree instance and its placement hold about 1.3 KB (docs/performance-history.md), what
// about 8 triangles of a flattened copy hold: a mesh of fewer triangles is copied, not instanced,
// and the triangle limit counts each placement as that many triangles, so that a file placing
// one small mesh millions of times cannot take more memory than the limit allows.
constexpr int64_t kMinInstancedTriangles = 8;
constexpr int64_t kPlacementTriangles = 8;

// Row-major 3x4 affine transform in double (the last row is (0, 0, 0, 1)).
using Affine = std::array<double, 12>;

Affine FromAssimp(const aiMatrix4x4& m) {
  return {m.a1, m.a2, m.a3, m.a4, m.b1, m.b2, m.b3, m.b4, m.c1, m.c2, m.c3, m.c4};
}

Affine Compose(const Affine& a, const Affine& b) {  // a * b
  Affine r{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 4; ++j) {
      double x = a[4 * i] * b[j] + a[4 * i + 1] * b[4 + j] + a[4 * i + 2] * b[8 + j];
      if (j == 3) x += a[4 * i + 3];
      r[4 * i + j] = x;
    }
  }
  return r;
}

// The same transform as a placement (linear part and translation).
MeshPlacement ToPlacement(const Affine& m) {
  return {Mat3d::FromRows({m[0], m[1], m[2]}, {m[4], m[5], m[6]}, {m[8], m[9], m[10]}),
          {m[3], m[7], m[11]}};
}

Vec3d Apply(const Affine& m, const aiVector3D& p) {
  const double x = p.x, y = p.y, z = p.z;
  return {m[0] * x + m[1] * y + m[2] * z + m[3], m[4] * x + m[5] * y + m[6] * z + m[7],
          m[8] * x + m[9] * y + m[10] * z + m[11]};
}

// The file system assimp sees: nothing. Assimp opens the files a model names (a glTF buffer's
// uri, an OBJ's mtllib) through its IO system, and a server must never open a path a request
// names (docs/service.md); ReadFileFromMemory serves the model's own bytes and asks this for the
// rest.
class NoFilesIOSystem : public Assimp::IOSystem {
 public:
  bool Exists(const char*) const override { return false; }
  char getOsSeparator() const override { return '/'; }
  Assimp::IOStream* Open(const char*, const char*) override { return nullptr; }
  void Close(Assimp::IOStream* stream) override { delete stream; }
};

// The file system assimp sees while importing a model: the model's references, read through a
// ReferenceReader (never by path), kept for the importer's lifetime and for the caller's digest.
// The first reference that cannot be read is remembered: it, not assimp's own message, refuses the
// file.
class ReferenceIOSystem : public Assimp::IOSystem {
 public:
  explicit ReferenceIOSystem(ReferenceReader read) : readReference_(std::move(read)) {}

  bool Exists(const char* path) const override { return Read(path) != nullptr; }
  char getOsSeparator() const override { return '/'; }
  Assimp::IOStream* Open(const char* path, const char* mode) override {
    if (mode == nullptr || std::string_view(mode).find_first_of("wa+") != std::string_view::npos)
      return nullptr;
    const std::string* bytes = Read(path);
    if (bytes == nullptr) return nullptr;
    return new Assimp::MemoryIOStream(reinterpret_cast<const uint8_t*>(bytes->data()),
                                      bytes->size(), /*own=*/false);
  }
  void Close(Assimp::IOStream* stream) override { delete stream; }

  // Reads a reference assimp does not open itself (a texture path of a material).
  const std::string* Read(const std::string& path) const {
    const std::string key = NormalizeModelPath(path);
    if (auto it = read_.find(key); it != read_.end()) return &it->second;
    if (failed_.count(key) || !readReference_) return nullptr;
    absl::StatusOr<std::string> bytes = readReference_(key);
    if (!bytes.ok()) {
      failed_.insert(key);
      if (firstError_.ok()) firstError_ = bytes.status();
      return nullptr;
    }
    return &read_.emplace(key, std::move(*bytes)).first->second;
  }
  const absl::Status& firstError() const { return firstError_; }
  std::map<std::string, std::string> TakeRead() { return std::move(read_); }

 private:
  ReferenceReader readReference_;
  mutable std::map<std::string, std::string> read_;
  mutable std::set<std::string> failed_;
  mutable absl::Status firstError_;
};

// The decoded textures of a model's materials, each image decoded once: embedded in the model
// (a GLB's buffer views, data: URIs; assimp names them "*<index>") or a referenced file.
class TextureLoader {
 public:
  TextureLoader(const aiScene& scene, const ReferenceIOSystem& references,
                const std::string& fieldPath, int64_t maxPixels)
      : scene_(scene), references_(references), fieldPath_(fieldPath), maxPixels_(maxPixels) {}

  // INVALID_ARGUMENT "<fieldPath>: texture '<path>' of material '<material>': <why>" when the
  // image is missing, too large or cannot be decoded.
  absl::StatusOr<std::shared_ptr<const Texture>> Load(const std::string& path,
                                                      const std::string& material) {
    if (auto it = decoded_.find(path); it != decoded_.end()) return it->second;
    const auto refuse = [&](const std::string& why) {
      return FieldError(
          fieldPath_, "texture " + Quoted(path) + " of material " + Quoted(material) + ": " + why);
    };
    auto texture = std::make_shared<Texture>();
    texture->name = path;
    const aiTexture* embedded = scene_.GetEmbeddedTexture(path.c_str());
    if (embedded != nullptr && embedded->mHeight > 0) {  // raw BGRA texels
      PB_RETURN_IF_ERROR(CheckPixels(embedded->mWidth, embedded->mHeight, refuse));
      if (embedded->pcData == nullptr) return refuse("the embedded image has no texels");
      texture->width = int(embedded->mWidth);
      texture->height = int(embedded->mHeight);
      const size_t texels = size_t(embedded->mWidth) * embedded->mHeight;
      texture->rgba.resize(4 * texels);
      for (size_t k = 0; k < texels; ++k) {
        const aiTexel& t = embedded->pcData[k];
        texture->rgba[4 * k] = t.r, texture->rgba[4 * k + 1] = t.g;
        texture->rgba[4 * k + 2] = t.b, texture->rgba[4 * k + 3] = t.a;
        texture->hasAlpha = texture->hasAlpha || t.a != 255;
      }
    } else {
      std::string_view bytes;
      if (embedded != nullptr) {
        if (embedded->pcData == nullptr) return refuse("the embedded image is empty");
        bytes = std::string_view(reinterpret_cast<const char*>(embedded->pcData), embedded->mWidth);
      } else if (path.empty() || path[0] == '*' || path.rfind("data:", 0) == 0) {
        return refuse("the model names an image it does not hold");
      } else {
        const std::string* read = references_.Read(path);
        if (read == nullptr) {
          if (!references_.firstError().ok()) return references_.firstError();
          return refuse("cannot read it");
        }
        bytes = *read;
      }
      StbImageInfo info;
      std::string error;
      if (!StbImageHeader(bytes, &info, &error))
        return refuse("not a PNG, JPEG, TGA or BMP image (" + error + ")");
      if (info.radiance) return refuse("a Radiance HDR image; textures are 8-bit images");
      PB_RETURN_IF_ERROR(CheckPixels(int64_t(info.width), int64_t(info.height), refuse));
      if (!StbDecodeRgba8(bytes, &texture->rgba, &error))
        return refuse("cannot decode it: " + error);
      texture->width = info.width;
      texture->height = info.height;
      texture->hasAlpha = info.channels == 2 || info.channels == 4;
    }
    std::shared_ptr<const Texture> out = std::move(texture);
    decoded_.emplace(path, out);
    return out;
  }

 private:
  template <typename Refuse>
  absl::Status CheckPixels(int64_t width, int64_t height, const Refuse& refuse) const {
    if (width < 1 || height < 1) return refuse("the image has no pixels");
    if (maxPixels_ > 0 && width * height > maxPixels_) {
      return refuse(Num(width) + " x " + Num(height) + " pixels, above the limit of " +
                    Num(maxPixels_));
    }
    return absl::OkStatus();
  }

  const aiScene& scene_;
  const ReferenceIOSystem& references_;
  const std::string& fieldPath_;
  int64_t maxPixels_;
  std::map<std::string, std::shared_ptr<const Texture>> decoded_;
};

TextureWrap WrapOf(aiTextureMapMode mode) {
  switch (mode) {
    case aiTextureMapMode_Clamp:
    case aiTextureMapMode_Decal:
      return TextureWrap::kClamp;
    case aiTextureMapMode_Mirror:
      return TextureWrap::kMirror;
    default:
      return TextureWrap::kRepeat;
  }
}

// KHR_texture_transform as the affine map of MapPlacement, from the aiUVTransform assimp's glTF 2
// importer stores: it negates the rotation and folds its flip of v and its rotation about the
// image centre into the translation; undone here to the extension's offset, rotation and scale,
// applied as the extension says: uv' = offset + R(rotation) (scale * uv), R = [c -s; s c].
std::array<double, 6> GltfTextureTransform(const aiUVTransform& t) {
  const double sx = t.mScaling.x, sy = t.mScaling.y;
  const double rotation = -double(t.mRotation);
  const double c = std::cos(rotation), s = std::sin(rotation);
  const double ox = t.mTranslation.x - 0.5 * sx * (-c + s + 1);
  const double oy = 0.5 * sy * (s + c - 1) + 1 - sy - t.mTranslation.y;
  return {c * sx, -s * sy, ox, s * sx, c * sy, oy};
}

// Reads map 0 of `type` into `map` and `at`; `srgb` for colour maps.
absl::Status ReadMap(const aiMaterial& material, aiTextureType type, bool srgb, bool gltf,
                     const std::string& materialName, TextureLoader& loader, TextureMap* map,
                     MapPlacement* at) {
  if (material.GetTextureCount(type) == 0) return absl::OkStatus();
  aiString path;
  unsigned uvSet = 0;
  aiTextureMapMode modes[2] = {aiTextureMapMode_Wrap, aiTextureMapMode_Wrap};
  if (material.GetTexture(type, 0, &path, nullptr, &uvSet, nullptr, nullptr, modes) !=
      aiReturn_SUCCESS)
    return absl::OkStatus();
  PB_ASSIGN_OR_RETURN(map->image, loader.Load(path.C_Str(), materialName));
  map->wrapX = WrapOf(modes[0]);
  map->wrapY = WrapOf(modes[1]);
  map->srgb = srgb;
  at->uvSet = uvSet < AI_MAX_NUMBER_OF_TEXTURECOORDS ? uvSet : 0;
  aiUVTransform transform;
  if (gltf &&
      material.Get(_AI_MATKEY_UVTRANSFORM_BASE, int(type), 0, transform) == aiReturn_SUCCESS)
    at->transform = GltfTextureTransform(transform);
  return absl::OkStatus();
}

// The diffuse part of an assimp material: glTF metallic-roughness (base colour x (1 - metallic),
// emissive factor x KHR_materials_emissive_strength), KHR_materials_pbrSpecularGlossiness's
// diffuse, else the classic colours (an OBJ's Kd, Ke); with `textures`, the maps and coverage
// too. Albedo at or above 1 is clamped just below 1 (energy would grow without bound), with a
// warning; the maps' values are at most 1, so the product stays below 1.
absl::StatusOr<FileMaterial> ReduceMaterial(const aiMaterial& material, const std::string& format,
                                            const std::string& where, TextureLoader* textures) {
  FileMaterial file;
  Material& out = file.material;
  aiString name;
  if (material.Get(AI_MATKEY_NAME, name) == aiReturn_SUCCESS) out.name = name.C_Str();
  aiColor4D base(1, 1, 1, 1);
  aiColor3D diffuse(1, 1, 1), emissive(0, 0, 0);
  float metallic = 0, strength = 1, glossiness = 0;
  const bool specularGlossiness =
      material.Get(AI_MATKEY_GLOSSINESS_FACTOR, glossiness) == aiReturn_SUCCESS;
  if (!specularGlossiness && material.Get(AI_MATKEY_BASE_COLOR, base) == aiReturn_SUCCESS) {
    if (material.Get(AI_MATKEY_METALLIC_FACTOR, metallic) != aiReturn_SUCCESS) metallic = 0;
    const double dielectric = 1.0 - std::clamp(double(metallic), 0.0, 1.0);
    out.albedo = Vec3d(base.r, base.g, base.b) * dielectric;
  } else if (material.Get(AI_MATKEY_COLOR_DIFFUSE, diffuse) == aiReturn_SUCCESS) {
    out.albedo = Vec3d(diffuse.r, diffuse.g, diffuse.b);
  } else {
    out.albedo = Vec3d(1, 1, 1);
  }
  if (material.Get(AI_MATKEY_COLOR_EMISSIVE, emissive) == aiReturn_SUCCESS) {
    if (material.Get(AI_MATKEY_EMISSIVE_INTENSITY, strength) != aiReturn_SUCCESS) strength = 1;
    out.emission = Vec3d(emissive.r, emissive.g, emissive.b) * double(strength);
  }
  // Negative or NaN factors are black; albedo 1 or more is clamped below 1.
  constexpr double kBelowOne = 1.0 - 1.0 / (1 << 20);
  bool clamped = false;
  for (double* c : {&out.albedo.x, &out.albedo.y, &out.albedo.z}) {
    if (!(*c >= 0)) *c = 0;
    if (*c >= 1) {
      *c = kBelowOne;
      clamped = true;
    }
  }
  for (double* c : {&out.emission.x, &out.emission.y, &out.emission.z})
    if (!(*c >= 0) || !std::isfinite(*c)) *c = 0;
  // A colour texture's factor is 1 by default in glTF (and MTL's Kd often is): the texels,
  // at most 1, are the albedo, and the clamp changes a white texel by 2^-20, not worth a warning.
  const bool textured = material.GetTextureCount(aiTextureType_BASE_COLOR) > 0 ||
                        material.GetTextureCount(aiTextureType_DIFFUSE) > 0;
  if (clamped && !textured)
    Logger("job")->warn("{}: material {} has an albedo of 1 or more; clamped to {}", where,
                        Quoted(out.name), kBelowOne);
  if (textures == nullptr) return file;

  // Coverage: glTF's alphaMode MASK cuts out below alphaCutoff and BLEND below 0.5 (no partial
  // transparency), OPAQUE ignores alpha; an OBJ's d below 1 or a map_d cuts out below 0.5.
  const bool gltf = format == "gltf" || format == "glb";
  float opacity = 1;
  if (material.Get(AI_MATKEY_OPACITY, opacity) == aiReturn_SUCCESS)
    out.coverage = std::isfinite(opacity) ? std::clamp(double(opacity), 0.0, 1.0) : 1.0;
  if (gltf) {
    aiString mode;
    float cutoff = 0.5f;
    if (material.Get(AI_MATKEY_GLTF_ALPHAMODE, mode) == aiReturn_SUCCESS) {
      if (std::string_view(mode.C_Str()) == "MASK") {
        if (material.Get(AI_MATKEY_GLTF_ALPHACUTOFF, cutoff) != aiReturn_SUCCESS) cutoff = 0.5f;
        out.alphaCutoff = std::isfinite(cutoff) ? std::clamp(double(cutoff), 0.0, 1.0) : 0.5;
      } else if (std::string_view(mode.C_Str()) == "BLEND") {
        out.alphaCutoff = 0.5;
      }
    }
    int twoSided = 0;
    if (material.Get(AI_MATKEY_TWOSIDED, twoSided) == aiReturn_SUCCESS) out.doubleSided = twoSided;
  } else if (format == "obj") {
    PB_RETURN_IF_ERROR(ReadMap(material, aiTextureType_OPACITY, /*srgb=*/false, false, out.name,
                               *textures, &out.coverageMap, &file.coverageAt));
    if (out.coverage < 1 || out.coverageMap.image) out.alphaCutoff = 0.5;
    if (out.coverage == 0) {
      Logger("job")->warn("{}: material {} has d 0 (wholly transparent): its triangles are cut out",
                          where, Quoted(out.name));
    }
  }

  PB_RETURN_IF_ERROR(ReadMap(material, aiTextureType_DIFFUSE, /*srgb=*/true, gltf, out.name,
                             *textures, &out.albedoMap, &file.albedoAt));
  if (MaxComponent(out.emission) > 0) {
    PB_RETURN_IF_ERROR(ReadMap(material, aiTextureType_EMISSIVE, /*srgb=*/true, gltf, out.name,
                               *textures, &out.emissionMap, &file.emissionAt));
  }
  return file;
}

// Linear RGBA of an assimp vertex colour: glTF's COLOR_0 is linear; PLY colours are display
// (sRGB-encoded) values.
std::array<float, 4> VertexColor(const aiColor4D& c, bool srgb) {
  const auto linear = [&](double x) {
    x = std::clamp(std::isfinite(x) ? x : 0.0, 0.0, 1.0);
    if (!srgb) return float(x);
    return float(x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4));
  };
  return {linear(c.r), linear(c.g), linear(c.b),
          float(std::clamp(std::isfinite(c.a) ? double(c.a) : 1.0, 0.0, 1.0))};
}

// The linear part of `m` applied to the vector d.
Vec3d ApplyLinear(const Affine& m, const aiVector3D& d) {
  const double x = d.x, y = d.y, z = d.z;
  return {m[0] * x + m[1] * y + m[2] * z, m[4] * x + m[5] * y + m[6] * z,
          m[8] * x + m[9] * y + m[10] * z};
}

// The file's punctual lights (glTF KHR_lights_punctual, as assimp reports them: colour x
// intensity in candela or lux, position and direction in the node's space, cone half-angles in
// radians), each placed by the node of its name; a light no node places is ignored with a warning,
// as are other kinds of lights and other formats' lights.
absl::StatusOr<std::vector<Light>> FileLights(const aiScene& scene,
                                              const std::map<std::string, Affine>& nodes,
                                              const std::string& format,
                                              const std::string& fieldPath) {
  std::vector<Light> out;
  if (scene.mNumLights == 0 || scene.mLights == nullptr) return out;
  if (format != "gltf" && format != "glb") {
    Logger("job")->info("{}: the file's {} light(s) are ignored (lights are read from glTF only)",
                        fieldPath, scene.mNumLights);
    return out;
  }
  for (unsigned i = 0; i < scene.mNumLights; ++i) {
    const aiLight* light = scene.mLights[i];
    if (light == nullptr) continue;
    const std::string name = light->mName.C_Str();
    const auto node = nodes.find(name);
    if (node == nodes.end()) {
      Logger("job")->warn("{}: light {} is placed by no node of the scene: ignored", fieldPath,
                          Quoted(name));
      continue;
    }
    const Affine& m = node->second;
    Vec3d power(light->mColorDiffuse.r, light->mColorDiffuse.g, light->mColorDiffuse.b);
    for (double* c : {&power.x, &power.y, &power.z}) {
      if (!(*c >= 0) || !std::isfinite(*c)) *c = 0;
      *c /= kLumensPerWatt;
      if (*c > kMaxEmitted) {
        return FieldError(fieldPath, "light " + Quoted(name) + " emits more than " +
                                         Num(kMaxEmitted * kLumensPerWatt) + " cd or lux");
      }
    }
    const Vec3d position = Apply(m, light->mPosition);
    Vec3d direction = ApplyLinear(m, light->mDirection);
    const double length = Length(direction);
    const bool directed =
        light->mType == aiLightSource_SPOT || light->mType == aiLightSource_DIRECTIONAL;
    if (directed && !(length > 0 && std::isfinite(length))) {
      return FieldError(fieldPath, "light " + Quoted(name) +
                                       ": its node's transform leaves it no "
                                       "direction");
    }
    if (!IsFinite(position))
      return FieldError(fieldPath, "light " + Quoted(name) + " has a non-finite position");
    if (directed) direction = direction / length;
    switch (light->mType) {
      case aiLightSource_POINT:
        out.push_back(PointLight{position, power});
        break;
      case aiLightSource_SPOT: {
        const double outer = std::clamp(double(light->mAngleOuterCone), 0.0, std::acos(-1.0) / 2);
        const double inner = std::clamp(double(light->mAngleInnerCone), 0.0, outer);
        out.push_back(SpotLight{position, direction, power, std::cos(inner), std::cos(outer)});
        break;
      }
      case aiLightSource_DIRECTIONAL:
        out.push_back(DirectionalLight{direction, power, 1});
        break;
      default:
        Logger("job")->warn("{}: light {} is of a kind glTF does not define: ignored", fieldPath,
                            Quoted(name));
        break;
    }
  }
  return out;
}

// The JSON of a glTF file: all of a .gltf, a GLB's first chunk (its sizes were checked by
// MeshFileProblem).
std::string_view GltfJsonOf(std::string_view bytes, const std::string& format) {
  if (format == "gltf") return bytes;
  if (bytes.size() < 20) return {};
  uint32_t length = 0;
  std::memcpy(&length, bytes.data() + 12, 4);
  return bytes.substr(20, length);
}

// The extensions a glTF file uses (`extensionsUsed`) that the bake does not read. Read from the
// file's JSON: assimp does not report them, and one it does not know would pass unnoticed.
std::vector<std::string> IgnoredGltfExtensions(std::string_view json, const aiScene& scene) {
  google::protobuf::Value root;
  if (!google::protobuf::util::JsonStringToMessage(std::string(json), &root).ok()) return {};
  if (!root.has_struct_value()) return {};
  const auto& fields = root.struct_value().fields();
  const auto used = fields.find("extensionsUsed");
  if (used == fields.end() || !used->second.has_list_value()) return {};
  // Read: they change what the bake sees. KHR_materials_emissive_strength only when the importer
  // reported it (assimp 5.2.5 does not).
  std::set<std::string> read = {
      "KHR_lights_punctual",        "KHR_texture_transform", "KHR_materials_pbrSpecularGlossiness",
      "KHR_draco_mesh_compression", "KHR_mesh_quantization", "EXT_meshopt_compression"};
  for (unsigned m = 0; m < scene.mNumMaterials; ++m) {
    float strength = 0;
    if (scene.mMaterials[m] != nullptr &&
        scene.mMaterials[m]->Get(AI_MATKEY_EMISSIVE_INTENSITY, strength) == aiReturn_SUCCESS)
      read.insert("KHR_materials_emissive_strength");
  }
  std::set<std::string> ignored;
  for (const google::protobuf::Value& name : used->second.list_value().values()) {
    if (name.has_string_value() && read.count(name.string_value()) == 0)
      ignored.insert(name.string_value());
  }
  return {ignored.begin(), ignored.end()};
}

// Whether an importer that lists `format` among its extensions reads `bytes`. When several
// importers list an extension (glTF 1 and 2 both list gltf and glb), assimp asks them; when none
// accepts, it tries every importer it has by signature (an STL file sent as gltf was read as
// STL), so the whole zoo of formats we do not support would be reachable. Formats with one
// importer (obj, ply) go to it directly and need no question.
bool ClaimedByAnImporterOf(std::string_view bytes, const std::string& format) {
  Assimp::Importer importer;
  std::vector<Assimp::BaseImporter*> claiming;
  for (size_t i = 0; i < importer.GetImporterCount(); ++i) {
    Assimp::BaseImporter* candidate = importer.GetImporter(i);
    std::set<std::string> extensions;
    candidate->GetExtensionList(extensions);
    if (extensions.count(format) > 0) claiming.push_back(candidate);
  }
  if (claiming.size() <= 1) return true;
  NoFilesIOSystem noFiles;
  Assimp::MemoryIOSystem io(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), &noFiles);
  const std::string file = std::string(AI_MEMORYIO_MAGIC_FILENAME) + "." + format;
  for (Assimp::BaseImporter* candidate : claiming)
    if (candidate->CanRead(file, &io, true)) return true;
  return false;
}

// Assimp splits a polygon of n vertices into triangles in O(n^2) time: a single OBJ face of 32000
// vertices (a 1 MB file) took 18 s, and the time grows without bound with the file. The sum of n^2
// over a file's polygons of more than 64 vertices (smaller ones cost about what their bytes do to
// read) is capped at what takes about a second: one face of 8192 vertices, or 1024 of 256.
constexpr unsigned kPolygonWorkFrom = 64;
constexpr double kMaxPolygonWork = 1 << 26;

}  // namespace

absl::StatusOr<ImportedMesh> ImportMesh(std::string_view bytes, const std::string& format,
                                        const std::string& name, const std::string& fieldPath,
                                        int64_t trianglesBefore, int64_t maxTriangles,
                                        int64_t flattenUpToTriangles,
                                        const ReferenceReader& readReference, bool fileMaterials,
                                        int64_t maxTexturePixels) {
  const std::string what = Quoted(name);
  // Windows tools write OBJ files with a UTF-8 byte-order mark, which assimp's OBJ reader takes
  // for part of the first line (that vertex lost: "vertex index out of range").
  if (format == "obj" && bytes.starts_with("\xEF\xBB\xBF")) bytes.remove_prefix(3);
  if (bytes.empty())
    return FieldError(fieldPath, "cannot import " + what + " as " + format + ": the file is empty");

  if (const std::string problem = MeshFileProblem(bytes, format); !problem.empty())
    return FieldError(fieldPath, "cannot import " + what + " as " + format + ": " + problem);

  if (!ClaimedByAnImporterOf(bytes, format)) {
    return FieldError(
        fieldPath, "cannot import " + what + " as " + format + ": it is not a " + format + " file");
  }

  const AssimpWarningCapture assimpWarnings;
  Assimp::Importer importer;
  // Without the file's materials, an OBJ's only references (its .mtl files) are not read: a
  // missing one is no error, as assimp's default material is not used either.
  auto* references =
      new ReferenceIOSystem(!fileMaterials && format == "obj" ? ReferenceReader() : readReference);
  importer.SetIOHandler(references);  // the importer owns it
  // Points and lines are dropped entirely rather than kept as separate meshes.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE,
                              aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  // Read and validate first, triangulate after: assimp's triangulation asserts (aborts) on faces
  // that index no vertex or past the mesh's vertices, which fuzzed PLY files produce.
  const aiScene* scene = nullptr;
  double polygonWork = 0;  // the sum of n^2 over polygons of n > kPolygonWorkFrom vertices
  struct {
    unsigned mesh = 0, face = 0, vertices = 0;
  } largest;
  try {
    scene = importer.ReadFileFromMemory(bytes.data(), bytes.size(), aiProcess_ValidateDataStructure,
                                        format.c_str());
    if (!references->firstError().ok()) return references->firstError();
    if (scene != nullptr && assimpWarnings.Saw("out-of-range indices")) {
      return FieldError(fieldPath, "cannot import " + what + " as " + format +
                                       ": some triangles index vertices past the end of their "
                                       "primitive's vertices (assimp would drop them)");
    }
    if (scene != nullptr) {
      for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const aiMesh* mesh = scene->mMeshes[m];
        if (mesh == nullptr || (mesh->mNumFaces > 0 && mesh->mFaces == nullptr))
          return FieldError(fieldPath, what + " has a malformed mesh");
        for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
          const aiFace& face = mesh->mFaces[f];
          if (face.mNumIndices == 0 || face.mIndices == nullptr)
            return FieldError(fieldPath, what + " has a face without vertices");
          for (unsigned k = 0; k < face.mNumIndices; ++k) {
            if (face.mIndices[k] >= mesh->mNumVertices)
              return FieldError(fieldPath, what + " has a vertex index out of range");
          }
          if (face.mNumIndices > kPolygonWorkFrom) {
            polygonWork += double(face.mNumIndices) * face.mNumIndices;
            if (face.mNumIndices > largest.vertices) largest = {m, f, face.mNumIndices};
          }
        }
      }
      if (polygonWork > kMaxPolygonWork) {
        return FieldError(
            fieldPath,
            what + " has polygons too large to triangulate in time: the squares of the " +
                "vertex counts of its faces of over 64 vertices sum to " +
                Num(int64_t(polygonWork)) + ", above " + Num(int64_t(kMaxPolygonWork)) +
                " (the largest, face " + Num(largest.face) + " of mesh " + Num(largest.mesh) +
                ", has " + Num(largest.vertices) + " vertices); triangulate them before export");
      }
      scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_SortByPType);
    }
  } catch (const std::exception& e) {
    return FieldError(fieldPath, "cannot import " + what + " as " + format + ": " + e.what());
  }
  if (scene == nullptr) {
    return FieldError(fieldPath,
                      "cannot import " + what + " as " + format + ": " + importer.GetErrorString());
  }

  // Walk the node tree (explicitly: a file's nesting depth is not ours to trust), counting
  // triangles before copying anything.
  struct Instance {
    const aiMesh* mesh;
    Affine transform;
    size_t node;  // the node's place in the walk
  };
  std::vector<Instance> instances;
  std::map<std::string, Affine> nodeTransforms;  // by node name, the first node of a name
  int64_t triangles = trianglesBefore;
  size_t nodes = 0;
  if (scene->mRootNode != nullptr) {
    std::vector<std::pair<const aiNode*, Affine>> stack{
        {scene->mRootNode, FromAssimp(scene->mRootNode->mTransformation)}};
    while (!stack.empty()) {
      const auto [node, transform] = stack.back();
      stack.pop_back();
      nodeTransforms.emplace(node->mName.C_Str(), transform);
      const size_t nodeIndex = nodes++;
      for (unsigned i = 0; i < node->mNumMeshes; ++i) {
        if (node->mMeshes[i] >= scene->mNumMeshes) continue;
        const aiMesh* mesh = scene->mMeshes[node->mMeshes[i]];
        if (!(mesh->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
        instances.push_back({mesh, transform, nodeIndex});
        triangles += mesh->mNumFaces;
      }
      for (unsigned i = 0; i < node->mNumChildren; ++i) {
        const aiNode* child = node->mChildren[i];
        stack.emplace_back(child, Compose(transform, FromAssimp(child->mTransformation)));
      }
    }
  }

  // What a node places (its meshes: a glTF mesh's primitives, one per material) is kept once, in
  // its own frame, as a group with its placements when several nodes place the same meshes and
  // the file places more than flattenUpToTriangles (groups numbered in the order of the walk, so
  // the same file gives the same groups).
  std::vector<std::vector<const aiMesh*>> placedBy(nodes);  // by node
  std::vector<const Affine*> transformOf(nodes, nullptr);
  for (const Instance& instance : instances) {
    placedBy[instance.node].push_back(instance.mesh);
    transformOf[instance.node] = &instance.transform;
  }
  std::vector<uint32_t> groupOfNode(nodes, 0);  // 1 + the group's index, or 0
  std::vector<size_t> writtenBy;                // per group, the node whose meshes are written
  std::vector<std::vector<MeshPlacement>> groupPlacements;
  if (triangles - trianglesBefore > flattenUpToTriangles) {
    std::map<std::vector<const aiMesh*>, int> uses;
    for (const auto& meshes : placedBy)
      if (!meshes.empty()) ++uses[meshes];
    std::map<std::vector<const aiMesh*>, uint32_t> groupOf;
    for (size_t n = 0; n < nodes; ++n) {
      if (placedBy[n].empty() || uses[placedBy[n]] < 2) continue;
      int64_t faces = 0;
      for (const aiMesh* mesh : placedBy[n]) faces += mesh->mNumFaces;
      if (faces < kMinInstancedTriangles) continue;  // copies are cheaper than instances
      auto [it, added] = groupOf.emplace(placedBy[n], uint32_t(groupPlacements.size() + 1));
      if (added) {
        groupPlacements.emplace_back();
        writtenBy.push_back(n);
      }
      groupOfNode[n] = it->second;
      groupPlacements[it->second - 1].push_back(ToPlacement(*transformOf[n]));
    }
    // The triangles held: a group's once, and each placement as kPlacementTriangles.
    triangles = trianglesBefore;
    for (const Instance& instance : instances) {
      const uint32_t group = groupOfNode[instance.node];
      if (group == 0 || writtenBy[group - 1] == instance.node)
        triangles += instance.mesh->mNumFaces;
    }
    for (const std::vector<MeshPlacement>& placements : groupPlacements)
      triangles += kPlacementTriangles * int64_t(placements.size());
  }
  if (maxTriangles > 0 && triangles > maxTriangles) {
    return FieldError(fieldPath, "the scene's triangles exceed the limit of " + Num(maxTriangles) +
                                     " with " + what);
  }

  // The texture maps of the materials the instances use (assimp records their paths; embedded
  // images are "*<index>").
  std::set<unsigned> materials;
  for (const Instance& instance : instances) materials.insert(instance.mesh->mMaterialIndex);
  for (const unsigned m : materials) {
    if (!fileMaterials) break;
    if (m >= scene->mNumMaterials || scene->mMaterials[m] == nullptr) continue;
    const aiMaterial* material = scene->mMaterials[m];
    for (const aiTextureType type : {aiTextureType_DIFFUSE, aiTextureType_BASE_COLOR,
                                     aiTextureType_EMISSIVE, aiTextureType_OPACITY}) {
      for (unsigned t = 0; t < material->GetTextureCount(type); ++t) {
        aiString texture;
        if (material->GetTexture(type, t, &texture) != aiReturn_SUCCESS) continue;
        const std::string path(texture.C_Str());
        if (path.empty() || path[0] == '*' || path.rfind("data:", 0) == 0) continue;
        if (scene->GetEmbeddedTexture(path.c_str()) != nullptr) continue;
        references->Read(path);
      }
    }
  }
  if (!references->firstError().ok()) return references->firstError();

  ImportedMesh out;
  out.groupPlacements = std::move(groupPlacements);
  TextureLoader textures(*scene, *references, fieldPath, maxTexturePixels);
  std::map<unsigned, uint32_t> fileMaterial;  // assimp's material index -> out.materials
  for (const unsigned m : materials) {
    if (m >= scene->mNumMaterials || scene->mMaterials[m] == nullptr) continue;
    fileMaterial.emplace(m, uint32_t(out.materials.size()));
    PB_ASSIGN_OR_RETURN(FileMaterial reduced,
                        ReduceMaterial(*scene->mMaterials[m], format, fieldPath,
                                       fileMaterials ? &textures : nullptr));
    out.materials.push_back(std::move(reduced));
  }
  // Vertex colours: glTF's and PLY's (an OBJ's are not part of its material model).
  const bool colorFormat =
      fileMaterials && (format == "gltf" || format == "glb" || format == "ply");
  if (colorFormat) {
    for (const Instance& instance : instances) {
      const auto it = fileMaterial.find(instance.mesh->mMaterialIndex);
      if (instance.mesh->HasVertexColors(0) && it != fileMaterial.end())
        out.materials[it->second].material.vertexColors = true;
    }
  }
  bool anyAlbedoMap = false, anyEmissionMap = false, anyCoverageMap = false, anyColors = false;
  for (const FileMaterial& m : out.materials) {
    anyAlbedoMap = anyAlbedoMap || m.material.albedoMap.image;
    anyEmissionMap = anyEmissionMap || m.material.emissionMap.image;
    anyCoverageMap = anyCoverageMap || m.material.coverageMap.image;
    anyColors = anyColors || m.material.vertexColors;
  }
  // The image coordinates of a map at vertex v of `mesh`.
  const auto imageUv = [](const aiMesh* mesh, unsigned v, const MapPlacement& at) {
    std::array<float, 2> xy{0, 0};
    if (mesh->mTextureCoords[at.uvSet] == nullptr) return xy;
    const aiVector3D& uv = mesh->mTextureCoords[at.uvSet][v];
    const double x = uv.x, y = 1.0 - double(uv.y);
    const std::array<double, 6>& m = at.transform;
    xy[0] = float(m[0] * x + m[1] * y + m[2]);
    xy[1] = float(m[3] * x + m[4] * y + m[5]);
    return xy;
  };

  for (const Instance& instance : instances) {
    const aiMesh* mesh = instance.mesh;
    const uint32_t group = groupOfNode[instance.node];
    if (group > 0 && writtenBy[group - 1] != instance.node) continue;  // its placements say where
    const size_t base = out.positions.size();
    if (base + mesh->mNumVertices > size_t(UINT32_MAX)) {
      return FieldError(fieldPath, what + " has too many vertices");
    }
    auto material = fileMaterial.find(mesh->mMaterialIndex);
    if (material == fileMaterial.end()) {  // a material index past the file's materials
      material = fileMaterial.emplace(mesh->mMaterialIndex, uint32_t(out.materials.size())).first;
      FileMaterial missing;
      missing.material = {"(missing)", Vec3d(0.5, 0.5, 0.5), Vec3d()};
      out.materials.push_back(std::move(missing));
    }
    const FileMaterial& used = out.materials[material->second];
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const Vec3d p = group > 0
                          ? Vec3d(mesh->mVertices[v].x, mesh->mVertices[v].y, mesh->mVertices[v].z)
                          : Apply(instance.transform, mesh->mVertices[v]);
      if (!IsFinite(p)) {
        return FieldError(fieldPath, what + " has a non-finite vertex position");
      }
      out.positions.push_back(p);
      if (anyAlbedoMap) out.albedoUv.push_back(imageUv(mesh, v, used.albedoAt));
      if (anyEmissionMap) out.emissionUv.push_back(imageUv(mesh, v, used.emissionAt));
      if (anyCoverageMap) out.coverageUv.push_back(imageUv(mesh, v, used.coverageAt));
      if (anyColors) {
        out.colors.push_back(used.material.vertexColors && mesh->HasVertexColors(0)
                                 ? VertexColor(mesh->mColors[0][v], format == "ply")
                                 : std::array<float, 4>{1, 1, 1, 1});
      }
    }
    // A node that mirrors its mesh keeps the mesh's front faces (glTF: the determinant of the
    // node's transform decides the winding): the copy's winding is reversed.
    const bool mirrored = group == 0 && Determinant(ToPlacement(instance.transform).linear) < 0;
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines sorted into this mesh
      for (int k = 0; k < 3; ++k) {
        const unsigned corner = mirrored && k > 0 ? 3 - k : k;
        if (face.mIndices[corner] >= mesh->mNumVertices) {
          return FieldError(fieldPath, what + " has a vertex index out of range");
        }
        out.indices.push_back(uint32_t(base + face.mIndices[corner]));
      }
      out.triangleMaterials.push_back(material->second);
      if (!out.groupPlacements.empty()) out.triangleGroups.push_back(group);
    }
  }
  if (fileMaterials) {
    PB_ASSIGN_OR_RETURN(out.lights, FileLights(*scene, nodeTransforms, format, fieldPath));
    if (format == "gltf" || format == "glb") {
      out.ignoredExtensions = IgnoredGltfExtensions(GltfJsonOf(bytes, format), *scene);
      for (const std::string& extension : out.ignoredExtensions) {
        Logger("job")->info(
            "{}: glTF extension {} ignored (it does not change diffuse transport, "
            "or is not read)",
            fieldPath, extension);
      }
    }
  }
  // Taken last: the textures above may have read references.
  if (!references->firstError().ok()) return references->firstError();
  out.references = references->TakeRead();
  if (out.indices.empty()) return FieldError(fieldPath, what + " contains no triangles");
  return out;
}

}  // namespace probebake::job_internal
