#include "probebake/job/file_refs.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <set>
#include <sstream>

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include "probebake/base/status.h"
#include "text.h"

namespace probebake {
namespace {

std::string Lowercase(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return out;
}

// The JSON of a .glb (its first chunk, of type JSON), or "" when the container is malformed.
std::string_view GlbJson(std::string_view bytes) {
  auto u32 = [&](size_t at) {
    uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4);  // little-endian, as glTF is; so are our platforms
    return v;
  };
  if (bytes.size() < 20 || bytes.substr(0, 4) != "glTF") return {};
  const uint32_t length = u32(12);
  if (bytes.substr(16, 4) != "JSON" || length > bytes.size() - 20) return {};
  return bytes.substr(20, length);
}

void AddGltfUris(std::string_view json, std::set<std::string>* out) {
  google::protobuf::Struct root;
  google::protobuf::util::JsonParseOptions options;
  options.ignore_unknown_fields = true;
  if (!google::protobuf::util::JsonStringToMessage(std::string(json), &root, options).ok()) return;
  for (const char* array : {"buffers", "images"}) {
    auto it = root.fields().find(array);
    if (it == root.fields().end() || !it->second.has_list_value()) continue;
    for (const google::protobuf::Value& item : it->second.list_value().values()) {
      if (!item.has_struct_value()) continue;
      auto uri = item.struct_value().fields().find("uri");
      if (uri == item.struct_value().fields().end() || !uri->second.has_string_value()) continue;
      const std::string& value = uri->second.string_value();
      if (value.empty() || value.rfind("data:", 0) == 0) continue;
      out->insert(NormalizeModelPath(value));
    }
  }
}

std::string Trimmed(std::string_view line) {
  const size_t first = line.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const size_t last = line.find_last_not_of(" \t\r");
  return std::string(line.substr(first, last - first + 1));
}

// The argument of a line "<keyword> <argument>" (keyword compared case-insensitively), or "".
std::string ArgumentOf(const std::string& line, std::string_view keyword) {
  if (line.size() <= keyword.size() || Lowercase(line.substr(0, keyword.size())) != keyword ||
      (line[keyword.size()] != ' ' && line[keyword.size()] != '\t'))
    return {};
  return Trimmed(line.substr(keyword.size()));
}

}  // namespace

std::string NormalizeModelPath(std::string_view modelPath) {
  std::string path(modelPath);
  std::replace(path.begin(), path.end(), '\\', '/');
  std::string normal = std::filesystem::path(path).lexically_normal().generic_string();
  return normal;
}

std::vector<std::string> ListModelReferences(
    std::string_view bytes, std::string_view format,
    const std::function<std::optional<std::string>(const std::string&)>& readReference) {
  std::set<std::string> refs;
  if (format == "gltf") AddGltfUris(bytes, &refs);
  if (format == "glb") AddGltfUris(GlbJson(bytes), &refs);
  if (format == "obj") {
    std::istringstream lines{std::string(bytes)};
    std::string line;
    std::vector<std::string> libraries;
    while (std::getline(lines, line)) {
      const std::string library = ArgumentOf(Trimmed(line), "mtllib");
      if (!library.empty()) libraries.push_back(NormalizeModelPath(library));
    }
    for (const std::string& library : libraries) {
      refs.insert(library);
      const std::optional<std::string> mtl = readReference(library);
      if (!mtl) continue;
      std::istringstream mtlLines(*mtl);
      while (std::getline(mtlLines, line)) {
        for (const char* keyword : {"map_kd", "map_ke", "map_d"}) {
          const std::string argument = ArgumentOf(Trimmed(line), keyword);
          if (argument.empty()) continue;
          // Options ("-bm 0.5") come first; the file name is the last word.
          const size_t space = argument.find_last_of(" \t");
          refs.insert(NormalizeModelPath(space == std::string::npos ? argument
                                                                    : argument.substr(space + 1)));
        }
      }
    }
  }
  return {refs.begin(), refs.end()};
}

bool IsMeshFormat(std::string_view format) {
  return format == "obj" || format == "ply" || format == "gltf" || format == "glb";
}

std::optional<std::string> MeshFormatOf(const v1::Mesh& mesh) {
  std::string format;
  if (!mesh.format().empty()) {
    format = Lowercase(mesh.format());
  } else if (!mesh.file().empty()) {
    const std::string extension = std::filesystem::path(mesh.file()).extension().string();
    if (!extension.empty()) format = Lowercase(extension.substr(1));
  }
  if (!IsMeshFormat(format)) return std::nullopt;
  return format;
}

std::vector<FileReference> ListFileReferences(const v1::JobSpec& job) {
  std::vector<FileReference> refs;
  const v1::Scene& scene = job.scene();
  for (int i = 0; i < scene.meshes_size(); ++i) {
    if (scene.meshes(i).file().empty()) continue;
    refs.push_back({FileReference::Kind::kMesh, i, job_internal::Index("scene.meshes", i) + ".file",
                    scene.meshes(i).file()});
  }
  if (scene.environment().has_map() && !scene.environment().map().file().empty()) {
    refs.push_back({FileReference::Kind::kEnvironmentMap, -1, "scene.environment.map.file",
                    scene.environment().map().file()});
  }
  for (int f = 0; f < scene.environment().map().faces_size(); ++f) {
    const std::string& file = scene.environment().map().faces(f).file();
    if (file.empty()) continue;
    refs.push_back({FileReference::Kind::kEnvironmentFace, -1,
                    job_internal::Index("scene.environment.map.faces", f) + ".file", file, f});
  }
  return refs;
}

std::vector<BlobReference> ListBlobReferences(const v1::JobSpec& job) {
  std::vector<BlobReference> refs;
  const v1::Scene& scene = job.scene();
  for (int i = 0; i < scene.meshes_size(); ++i) {
    if (scene.meshes(i).has_blob())
      refs.push_back({job_internal::Index("scene.meshes", i) + ".blob", scene.meshes(i).blob()});
  }
  if (!scene.environment().has_map()) return refs;
  const v1::EnvironmentMap& map = scene.environment().map();
  if (map.has_blob()) refs.push_back({"scene.environment.map.blob", map.blob()});
  for (int f = 0; f < map.faces_size(); ++f) {
    if (map.faces(f).has_blob())
      refs.push_back(
          {job_internal::Index("scene.environment.map.faces", f) + ".blob", map.faces(f).blob()});
  }
  return refs;
}

absl::Status ReplaceFileWithBlob(const FileReference& ref, const v1::Digest& digest,
                                 v1::JobSpec* job) {
  v1::Scene* scene = job->mutable_scene();
  if (ref.kind == FileReference::Kind::kMesh) {
    if (ref.meshIndex < 0 || ref.meshIndex >= scene->meshes_size() ||
        scene->meshes(ref.meshIndex).file() != ref.relativePath) {
      return FieldError(ref.fieldPath, "the job holds no file reference " +
                                           job_internal::Quoted(ref.relativePath) + " here");
    }
    v1::Mesh* mesh = scene->mutable_meshes(ref.meshIndex);
    const std::optional<std::string> format = MeshFormatOf(*mesh);
    if (!format) {
      return FieldError(ref.fieldPath, "unknown mesh format of " +
                                           job_internal::Quoted(ref.relativePath) +
                                           " (expected .obj, .ply, .gltf or .glb, or a format)");
    }
    mesh->set_format(*format);
    *mesh->mutable_blob() = digest;
    mesh->clear_file();
    return absl::OkStatus();
  }
  if (ref.kind == FileReference::Kind::kEnvironmentFace) {
    v1::EnvironmentMap* map = scene->mutable_environment()->mutable_map();
    if (!scene->environment().has_map() || ref.faceIndex < 0 ||
        ref.faceIndex >= map->faces_size() ||
        map->faces(ref.faceIndex).file() != ref.relativePath) {
      return FieldError(ref.fieldPath, "the job holds no file reference " +
                                           job_internal::Quoted(ref.relativePath) + " here");
    }
    *map->mutable_faces(ref.faceIndex)->mutable_blob() = digest;
    map->mutable_faces(ref.faceIndex)->clear_file();
    return absl::OkStatus();
  }
  if (!scene->environment().has_map() || scene->environment().map().file() != ref.relativePath) {
    return FieldError(ref.fieldPath, "the job holds no file reference " +
                                         job_internal::Quoted(ref.relativePath) + " here");
  }
  v1::EnvironmentMap* map = scene->mutable_environment()->mutable_map();
  *map->mutable_blob() = digest;
  map->clear_file();
  return absl::OkStatus();
}

}  // namespace probebake
