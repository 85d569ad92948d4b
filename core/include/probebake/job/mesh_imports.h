// Mesh files imported in one process and handed to another. An asset-check child imports a job's
// mesh files (runtime/asset_check.h) and hands the imports to its parent, which then builds the
// job from them: the parent (the server, the local CLI) never runs an importer on a client's file.
//
// An entry holds one job mesh's import as BuildBakeJob uses it: the triangles in the file's world
// space (before the job's transform), the file's materials with their textures decoded, per-vertex
// image coordinates and colours, the file's lights and ignored extensions, and the digests of the
// files the model referenced. It is bound to what was imported: the mesh's index in the job, the
// SHA-256 of the file's bytes, its format and whether the file's own materials were read.
//
// The serialized form is for a child and its parent on one machine: native byte order, never
// stored or sent elsewhere. Parse() checks every count against the bytes left, so a damaged
// hand-over is refused, not trusted.
#pragma once

#include <map>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/limits.h"
#include "probebake/scene/scene.h"
#include "probebake/v1/job.pb.h"

namespace probebake {

class MeshImports {
 public:
  // The entry of job mesh `mesh` (its index in scene.meshes); null when there is none.
  const std::string* Find(int mesh) const;
  // Sets the entry of job mesh `mesh` (BuildBakeJob writes entries; they are opaque elsewhere).
  void Put(int mesh, std::string entry);
  size_t size() const { return entries_.size(); }

  std::string Serialize() const;
  // INTERNAL "mesh imports: ..." when `bytes` is not what Serialize() wrote.
  static absl::StatusOr<MeshImports> Parse(std::string_view bytes);

 private:
  std::map<int, std::string> entries_;
};

// What BuildBakeJob does with mesh imports (both may be null: it imports in process).
struct MeshImportHandoff {
  // Every mesh file the build imports is recorded here (the child's side).
  MeshImports* record = nullptr;
  // Mesh files are not imported but taken from here (the parent's side). A mesh file without an
  // entry, or whose entry is bound to other bytes, format or material choice, is INTERNAL: the two
  // processes disagree, and importing in process is what the hand-over exists to avoid. The mesh
  // file's bytes are still read (its digest keys the job), the files it references are not.
  const MeshImports* use = nullptr;
};

// BuildBakeJob (job.h) recording the mesh files' imports or building from recorded ones: the
// same BakeJob, bit for bit, either way.
absl::StatusOr<BakeJob> BuildBakeJob(const v1::JobSpec& job, const AssetSource& assets,
                                     const JobLimits& limits, const MeshImportHandoff& handoff);

// LoadBakeJob (job.h) with a hand-over.
absl::StatusOr<BakeJob> LoadBakeJob(const std::string& path, const JobLimits& limits,
                                    const MeshImportHandoff& handoff);

}  // namespace probebake
