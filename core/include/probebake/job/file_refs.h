// The CLI's view of a job's asset files: list every `file` reference so it can upload the files
// as blobs, then rewrite each reference into `blob` (docs/job-format.md: the server never reads
// client paths). After the rewrite, the job digest and scene digest are unchanged: both are
// computed with every file reference replaced by the digest of its content.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "probebake/v1/job.pb.h"

namespace probebake {

struct FileReference {
  enum class Kind { kMesh, kEnvironmentMap, kEnvironmentFace };
  Kind kind = Kind::kMesh;
  int meshIndex = -1;        // kMesh: index into scene.meshes
  std::string fieldPath;     // "scene.meshes[3].file", "scene.environment.map.file", ...
  std::string relativePath;  // the path as written in the job (relative to the job file)
  int faceIndex = -1;        // kEnvironmentFace: index into scene.environment.map.faces
};

// Every non-empty `file` in `job`, meshes in order, then the environment map or its faces.
std::vector<FileReference> ListFileReferences(const v1::JobSpec& job);

// An uploaded asset a job names: the digest and the field that names it ("scene.meshes[2].blob").
struct BlobReference {
  std::string fieldPath;
  v1::Digest digest;
};

// Every `blob` in `job`, in the order of ListFileReferences: what a server must hold (and a
// cluster backend copy) before the job can bake.
std::vector<BlobReference> ListBlobReferences(const v1::JobSpec& job);

// Replaces the reference `ref` (from ListFileReferences on this job) by `digest`: a mesh gets
// `blob` and `format` (its explicit format, lowercased, else its file extension), an environment
// map or cube face gets `blob`; `file` is cleared. INVALID_ARGUMENT naming the field when the job
// no longer holds that reference or a mesh file's format is unknown.
absl::Status ReplaceFileWithBlob(const FileReference& ref, const v1::Digest& digest,
                                 v1::JobSpec* job);

// True for the mesh formats the importer reads: "obj", "ply", "gltf", "glb" (lowercase).
bool IsMeshFormat(std::string_view format);

// The format of a mesh: its `format` lowercased when given, else its file's extension lowercased
// (no dot); nullopt when neither names a mesh format.
std::optional<std::string> MeshFormatOf(const v1::Mesh& mesh);

// The key of a file a model references (a glTF buffer or image uri, an OBJ mtllib or texture
// map): '\\' read as '/', "." and "a/.." segments removed, as std::filesystem's lexically_normal.
// The same on the CLI, a local bake and the server, so mesh.references keys match what assimp asks.
std::string NormalizeModelPath(std::string_view modelPath);

// The files a model of `format` may reference, normalized, sorted, without duplicates: a glTF's
// (or GLB's JSON chunk's) buffers[].uri and images[].uri that are not data: URIs, an OBJ's mtllib
// files and their map_Kd, map_Ke and map_d textures (`readReference` reads an .mtl; nullopt when
// it cannot, which lists no textures of it). A superset of what an import reads: the CLI uploads
// these, the importer opens what it needs. Never fails: unparsable bytes list nothing.
std::vector<std::string> ListModelReferences(
    std::string_view bytes, std::string_view format,
    const std::function<std::optional<std::string>(const std::string&)>& readReference);

}  // namespace probebake
