// Small glTF files and PNG images written by tests of mesh files' own materials and lights.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

#include "absl/strings/escaping.h"
#include "job/stb_image_write_static.h"

namespace probebake::testing {

// A PNG of width x height RGBA texels (row 0 the top).
inline std::string Png(int width, int height, const std::vector<uint8_t>& rgba) {
  std::string out;
  stbi_write_png_to_func(
      [](void* context, void* data, int size) {
        static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size));
      },
      &out, width, height, 4, rgba.data(), width * 4);
  return out;
}

// The 2 x 2 test image: red, green (top row), blue, white (bottom row), opaque.
inline std::string Quadrants() {
  return Png(2, 2, {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 255});
}

template <typename T>
void Append(std::string* bytes, std::initializer_list<T> values) {
  for (T v : values) bytes->append(reinterpret_cast<const char*>(&v), sizeof v);
}

// A glTF quad (0,0,0) (1,0,0) (1,1,0) (0,1,0) facing +z, TEXCOORD_0 = `uv` (glTF's convention: v
// down), COLOR_0 = `colors` when given, material `material` (a JSON object), images `images`
// (JSON array) and textures with `samplers`.
inline std::string GltfQuad(const std::vector<float>& uv, const std::vector<float>& colors,
                            const std::string& material, const std::string& images,
                            const std::string& samplers = "[{}]") {
  std::string bin;
  Append<float>(&bin, {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0});
  for (float x : uv) Append<float>(&bin, {x});
  for (float x : colors) Append<float>(&bin, {x});
  Append<uint16_t>(&bin, {0, 1, 2, 0, 2, 3});
  const size_t uvAt = 48, colorAt = uvAt + 32, indexAt = colorAt + 4 * colors.size();
  std::string attributes = R"("POSITION": 0, "TEXCOORD_0": 1)";
  std::string accessors =
      R"({"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
          "min": [0, 0, 0], "max": [1, 1, 0]},
         {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
         {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"})";
  std::string views = R"({"buffer": 0, "byteOffset": 0, "byteLength": 48},
      {"buffer": 0, "byteOffset": 48, "byteLength": 32},
      {"buffer": 0, "byteOffset": )" +
                      std::to_string(indexAt) + R"(, "byteLength": 12})";
  if (!colors.empty()) {
    attributes += R"(, "COLOR_0": 3)";
    accessors += R"(, {"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC4"})";
    views +=
        R"(, {"buffer": 0, "byteOffset": )" + std::to_string(colorAt) + R"(, "byteLength": 64})";
  }
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
    "extensionsUsed": ["KHR_texture_transform"],
    "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {)" +
         attributes + R"(}, "indices": 2, "material": 0}]}],
    "materials": [)" +
         material + R"(],
    "images": )" +
         images + R"(, "samplers": )" + samplers + R"(,
    "textures": [{"source": 0, "sampler": 0}],
    "accessors": [)" +
         accessors + R"(],
    "bufferViews": [)" +
         views + R"(],
    "buffers": [{"byteLength": )" +
         std::to_string(bin.size()) + R"(, "uri": "data:application/octet-stream;base64,)" +
         absl::Base64Escape(bin) + R"("}]})";
}

// A glTF with one quad far below (a file needs triangles) and one KHR_lights_punctual light
// `light` (JSON) on a node `node` (JSON fields), or none.
inline std::string GltfWithLight(const std::string& light, const std::string& node) {
  std::string bin;
  Append<float>(&bin, {-1, -1, -5, 1, -1, -5, 1, 1, -5, -1, 1, -5});
  Append<uint16_t>(&bin, {0, 1, 2, 0, 2, 3});
  const bool lit = !light.empty();
  return R"({"asset": {"version": "2.0"}, "scene": 0,
    "scenes": [{"nodes": )" +
         std::string(lit ? "[0, 1]" : "[0]") + R"(}],
    )" +
         (lit ? R"("extensionsUsed": ["KHR_lights_punctual"],
    "extensions": {"KHR_lights_punctual": {"lights": [)" +
                    light + R"(]}},)"
              : std::string()) +
         R"(
    "nodes": [{"mesh": 0}, {"name": "lamp", )" +
         node +
         R"(, "extensions": {"KHR_lights_punctual": {"light": 0}}}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1,
                                "material": 0}]}],
    "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1],
                   "metallicFactor": 0}}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                   "min": [-1, -1, -5], "max": [1, 1, -5]},
                  {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                    {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
    "buffers": [{"byteLength": 60, "uri": "data:application/octet-stream;base64,)" +
         absl::Base64Escape(bin) + R"("}]})";
}

}  // namespace probebake::testing
