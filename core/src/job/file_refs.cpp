#include "probebake/job/file_refs.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

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

}  // namespace

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
