// BuildBakeJob: assets, world-space scene, digests.
#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <map>
#include <utility>

#include "cube_map.h"
#include "env_map.h"
#include "errors.h"
#include "imported_mesh_codec.h"
#include "mesh_import.h"
#include "probebake/base/check.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/base/version.h"
#include "probebake/job/digest.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"
#include "probebake/job/mesh_imports.h"
#include "probebake/job/validate.h"
#include "text.h"

namespace probebake {
namespace {

using job_internal::Index;
using job_internal::Num;
using job_internal::Quoted;

// Protobuf's deterministic binary form (map entries sorted; the same bytes in every run of the
// same build), the input of every digest.
std::string DeterministicBytes(const google::protobuf::Message& message) {
  std::string bytes;
  {
    google::protobuf::io::StringOutputStream stream(&bytes);
    google::protobuf::io::CodedOutputStream coded(&stream);
    coded.SetSerializationDeterministic(true);
    // Fails only for messages over 2 GiB, which the limits and the RPC layer exclude.
    PB_CHECK(message.SerializePartialToCodedStream(&coded));
  }
  return bytes;
}

Vec3d ToVec3(const google::protobuf::RepeatedField<double>& f, Vec3d fallback = {}) {
  return f.size() == 3 ? Vec3d(f[0], f[1], f[2]) : fallback;
}

// Unit vector along a validated non-zero finite vector, scaled first so that tiny or huge
// components neither under- nor overflow.
Vec3d UnitVector(const Vec3d& v) {
  return Normalize(v / MaxComponent(Abs(v)));
}

double CosDegrees(double degrees) {
  return degrees == 0 ? 1.0 : std::cos(degrees * (M_PI / 180));
}

struct Box {
  Vec3d lo{DBL_MAX, DBL_MAX, DBL_MAX};
  Vec3d hi{-DBL_MAX, -DBL_MAX, -DBL_MAX};
  void Add(const Vec3d& p) {
    lo = Min(lo, p);
    hi = Max(hi, p);
  }
};

// The bytes of a mesh or environment map, from `file` or `blob`; `fieldPath` names the referencing
// field for errors.
absl::StatusOr<std::string> ReadAsset(const std::string& file, const v1::Digest* blob,
                                      const std::string& path, const AssetSource& assets,
                                      const JobLimits& limits) {
  const std::string fieldPath = path + (file.empty() ? ".blob" : ".file");
  absl::StatusOr<std::string> bytes =
      file.empty() ? assets.ReadBlob(*blob, fieldPath) : assets.ReadFile(file, fieldPath);
  if (!bytes.ok()) return bytes.status();
  if (limits.maxAssetBytes > 0 && int64_t(bytes->size()) > limits.maxAssetBytes) {
    return FieldError(
        fieldPath, Num(bytes->size()) + " bytes, above the limit of " + Num(limits.maxAssetBytes));
  }
  return bytes;
}

std::string AssetName(const std::string& file, const v1::Digest& blob) {
  return file.empty() ? "blob " + blob.hash() : file;
}

// Moves a file's light by a mesh's row-major 4x4 `transform` (last row 0 0 0 1): positions as
// points, directions as vectors (renormalized); intensities are unchanged.
template <typename Transform>
absl::Status TransformLight(const Transform& t, const std::string& path, Light* light) {
  const auto point = [&](const Vec3d& p) {
    return Vec3d{t[0] * p.x + t[1] * p.y + t[2] * p.z + t[3],
                 t[4] * p.x + t[5] * p.y + t[6] * p.z + t[7],
                 t[8] * p.x + t[9] * p.y + t[10] * p.z + t[11]};
  };
  const auto vector = [&](const Vec3d& d) {
    return Normalize(Vec3d{t[0] * d.x + t[1] * d.y + t[2] * d.z,
                           t[4] * d.x + t[5] * d.y + t[6] * d.z,
                           t[8] * d.x + t[9] * d.y + t[10] * d.z});
  };
  if (auto* p = std::get_if<PointLight>(light)) {
    p->position = point(p->position);
    if (!IsFinite(p->position)) return FieldError(path + ".transform", "moves a light to infinity");
  } else if (auto* s = std::get_if<SpotLight>(light)) {
    s->position = point(s->position);
    s->direction = vector(s->direction);
    if (!IsFinite(s->position) || !IsFinite(s->direction))
      return FieldError(path + ".transform", "moves a light to infinity");
  } else if (auto* d = std::get_if<DirectionalLight>(light)) {
    d->direction = vector(d->direction);
  }
  return absl::OkStatus();
}

// An instanced mesh as world-space copies, one per placement. Refused when the copies would hold
// more vertices than 32-bit indices reach.
absl::StatusOr<TriangleMesh> PlacedCopies(const TriangleMesh& mesh, const std::string& path) {
  TriangleMesh out;
  out.name = mesh.name;
  out.material = mesh.material;
  const size_t vertices = mesh.positions.size() * mesh.placements.size();
  if (vertices > size_t(UINT32_MAX)) {
    return FieldError(path, "an emissive mesh placed " + Num(mesh.placements.size()) +
                                " times holds too many vertices");
  }
  for (const MeshPlacement& placement : mesh.placements) {
    const uint32_t base = uint32_t(out.positions.size());
    for (const Vec3d& p : mesh.positions) out.positions.push_back(placement.Apply(p));
    for (uint32_t index : mesh.indices) out.indices.push_back(base + index);
    out.albedoUv.insert(out.albedoUv.end(), mesh.albedoUv.begin(), mesh.albedoUv.end());
    out.emissionUv.insert(out.emissionUv.end(), mesh.emissionUv.begin(), mesh.emissionUv.end());
    out.coverageUv.insert(out.coverageUv.end(), mesh.coverageUv.begin(), mesh.coverageUv.end());
    out.colors.insert(out.colors.end(), mesh.colors.begin(), mesh.colors.end());
  }
  return out;
}

// Builds the world-space mesh of job mesh `i` and makes its reference canonical.
class MeshBuilder {
 public:
  // `jobLights`: the job's own lights, added after the meshes'.
  MeshBuilder(const AssetSource& assets, const JobLimits& limits, int64_t jobLights,
              const MeshImportHandoff& handoff)
      : assets_(assets), limits_(limits), jobLights_(jobLights), handoff_(handoff) {}

  // Mesh `index` of the job. `material`: the index of the job's material for the mesh; -1 uses
  // the file's own materials.
  absl::Status Add(const v1::Mesh& spec, int meshIndex, int64_t material, v1::Mesh* canonical,
                   Scene* scene) {
    const std::string path = Index("scene.meshes", meshIndex);
    job_internal::ImportedMesh raw;
    if (!spec.file().empty() || spec.has_blob()) {
      PB_ASSIGN_OR_RETURN(const std::string bytes,
                          ReadAsset(spec.file(), &spec.blob(), path, assets_, limits_));
      const std::string format = *MeshFormatOf(spec);  // validated
      if (!spec.file().empty()) *canonical->mutable_blob() = DigestOf(bytes);
      canonical->clear_file();
      canonical->set_format(format);
      const std::string fieldPath = path + (spec.file().empty() ? ".blob" : ".file");
      const std::string name = AssetName(spec.file(), spec.blob());
      // A `file` model's references are files beside it; a `blob` model's are the blobs its
      // `references` map names.
      const job_internal::ReferenceReader readReference =
          [&](const std::string& modelPath) -> absl::StatusOr<std::string> {
        if (!spec.file().empty())
          return assets_.ReadReferencedFile(spec.file(), modelPath, fieldPath);
        const auto it = spec.references().find(modelPath);
        if (it == spec.references().end()) {
          return FieldError(path + ".references", Quoted(name) + " references " +
                                                      Quoted(modelPath) + ", which is not listed");
        }
        const std::string field = path + ".references[" + Quoted(modelPath) + "]";
        PB_ASSIGN_OR_RETURN(std::string referenced, assets_.ReadBlob(it->second, field));
        if (limits_.maxAssetBytes > 0 && int64_t(referenced.size()) > limits_.maxAssetBytes) {
          return FieldError(field, Num(referenced.size()) + " bytes, above the limit of " +
                                       Num(limits_.maxAssetBytes));
        }
        return referenced;
      };
      const job_internal::ImportBinding binding{meshIndex, Sha256Hex(bytes), format, material < 0};
      if (handoff_.use != nullptr) {
        const std::string* entry = handoff_.use->Find(meshIndex);
        if (entry == nullptr) {
          return absl::InternalError("mesh imports: no entry for " + path +
                                     " (the asset check imported another job)");
        }
        PB_ASSIGN_OR_RETURN(raw, job_internal::DecodeImportedMesh(*entry, binding));
      } else {
        PB_ASSIGN_OR_RETURN(raw,
                            job_internal::ImportMesh(
                                bytes, format, name, fieldPath, triangles_, limits_.maxTriangles,
                                limits_.flattenUpToTriangles, readReference,
                                /*fileMaterials=*/material < 0, limits_.maxTexturePixels));
        for (const auto& [modelPath, referenced] : raw.references)
          raw.referenceDigests[modelPath] = {Sha256Hex(referenced), int64_t(referenced.size())};
        raw.references.clear();
        if (handoff_.record != nullptr)
          handoff_.record->Put(meshIndex, job_internal::EncodeImportedMesh(binding, raw));
      }
      // The job digest covers what the import read, whoever supplied it.
      canonical->clear_references();
      for (const auto& [modelPath, digest] : raw.referenceDigests) {
        v1::Digest& d = (*canonical->mutable_references())[modelPath];
        d.set_hash(digest.sha256);
        d.set_size_bytes(digest.sizeBytes);
      }
      for (const std::string& extension : raw.ignoredExtensions)
        ignored_.push_back(path + ": " + extension);
    } else {
      raw.positions.reserve(size_t(spec.positions_size() / 3));
      for (int k = 0; k + 2 < spec.positions_size(); k += 3)
        raw.positions.emplace_back(spec.positions(k), spec.positions(k + 1), spec.positions(k + 2));
      raw.indices.assign(spec.indices().begin(), spec.indices().end());
    }
    triangles_ += int64_t(raw.indices.size() / 3);

    TriangleMesh mesh;
    mesh.name = spec.name();
    mesh.material = material < 0 ? 0 : uint32_t(material);
    mesh.positions = std::move(raw.positions);
    // The vertices of groups (meshes the file places more than once) stay in their own frame: the
    // job's transform goes into the groups' placements.
    std::vector<uint8_t> grouped;
    if (!raw.triangleGroups.empty()) {
      grouped.assign(mesh.positions.size(), 0);
      for (size_t t = 0; t < raw.triangleGroups.size(); ++t)
        if (raw.triangleGroups[t] > 0)
          for (int k = 0; k < 3; ++k) grouped[raw.indices[3 * t + size_t(k)]] = 1;
    }
    std::vector<std::vector<MeshPlacement>> groups = std::move(raw.groupPlacements);
    if (spec.transform_size() == 16) {
      const auto& t = spec.transform();
      const MeshPlacement job{
          Mat3d::FromRows({t[0], t[1], t[2]}, {t[4], t[5], t[6]}, {t[8], t[9], t[10]}),
          {t[3], t[7], t[11]}};
      // The job's transform keeps the winding (docs/job-format.md: a mirroring transform turns
      // the front faces with it), while a placement keeps the front faces (scene.h, as a
      // mirroring glTF node does): a mirroring job transform reverses the groups' own winding to
      // say the same.
      if (!raw.triangleGroups.empty() && Determinant(job.linear) < 0) {
        for (size_t k = 0; k + 2 < raw.indices.size(); k += 3)
          if (raw.triangleGroups[k / 3] > 0) std::swap(raw.indices[k + 1], raw.indices[k + 2]);
      }
      for (size_t i = 0; i < mesh.positions.size(); ++i) {
        if (!grouped.empty() && grouped[i]) continue;
        Vec3d& p = mesh.positions[i];
        p = job.Apply(p);
        if (!IsFinite(p)) {
          return FieldError(path + ".transform", "transformed positions overflow");
        }
      }
      for (std::vector<MeshPlacement>& placements : groups) {
        for (MeshPlacement& placement : placements) {
          placement = {job.linear * placement.linear, job.Apply(placement.translation)};
          if (!IsFinite(placement.translation) || !IsFinite(placement.linear.Row(0)) ||
              !IsFinite(placement.linear.Row(1)) || !IsFinite(placement.linear.Row(2))) {
            return FieldError(path + ".transform", "transformed node placements overflow");
          }
        }
      }
    }
    // A placement that flattens its mesh (a node scaled to zero, as files hide parts) holds no
    // triangle of non-zero area, like a flattened copy whose triangles are all dropped below.
    int64_t flat = 0;
    for (std::vector<MeshPlacement>& placements : groups) {
      const auto before = placements.size();
      std::erase_if(placements, [](const MeshPlacement& placement) {
        const Mat3d& m = placement.linear;
        const double det = Determinant(m);
        return !(std::abs(det) > 1e-14 * Length(m.Row(0)) * Length(m.Row(1)) * Length(m.Row(2)));
      });
      flat += int64_t(before - placements.size());
    }
    if (flat > 0) Logger("job")->info("{}: dropped {} placement(s) of zero volume", path, flat);

    // Drop triangles without a meaningful normal: zero area (repeated or collinear vertices), or
    // so thin that the cross product is rounding noise (sin of the angle at a below 1e-14).
    int64_t dropped = 0;
    std::vector<uint32_t> keptMaterials;  // per kept triangle, with the file's materials
    std::vector<uint32_t> keptGroups;     // per kept triangle, with groups
    mesh.indices.reserve(raw.indices.size());
    for (size_t k = 0; k + 2 < raw.indices.size(); k += 3) {
      const Vec3d& a = mesh.positions[raw.indices[k]];
      const Vec3d e1 = mesh.positions[raw.indices[k + 1]] - a;
      const Vec3d e2 = mesh.positions[raw.indices[k + 2]] - a;
      const double n = Length(Cross(e1, e2));
      if (!(n >= DBL_MIN && std::isfinite(n) && n > 1e-14 * Length(e1) * Length(e2))) {
        ++dropped;
        continue;
      }
      mesh.indices.insert(mesh.indices.end(), raw.indices.begin() + k, raw.indices.begin() + k + 3);
      if (material < 0) keptMaterials.push_back(raw.triangleMaterials[k / 3]);
      if (!raw.triangleGroups.empty()) keptGroups.push_back(raw.triangleGroups[k / 3]);
    }
    if (dropped > 0) {
      Logger("job")->info("{}: dropped {} zero-area triangle(s) of {}", path, dropped,
                          raw.indices.size() / 3);
    }
    if (mesh.indices.empty()) {
      return FieldError(path, "no triangle with a non-zero area");
    }
    if (material >= 0 && keptGroups.empty()) {
      scene->meshes.push_back(std::move(mesh));
      return absl::OkStatus();
    }
    // The file's lights, moved by the mesh's transform like its vertices.
    if (material < 0 && !raw.lights.empty()) {
      // With the job's own lights (counted against the limit by validation).
      if (limits_.maxLights > 0 && int64_t(scene->lights.size() + raw.lights.size()) + jobLights_ >
                                       int64_t(limits_.maxLights)) {
        return FieldError(path, "the file's " + Num(raw.lights.size()) +
                                    " lights bring the scene's lights above the limit of " +
                                    Num(limits_.maxLights));
      }
      for (Light& light : raw.lights) {
        if (spec.transform_size() == 16) {
          PB_RETURN_IF_ERROR(TransformLight(spec.transform(), path, &light));
        }
        scene->lights.push_back(light);
      }
    }
    // One scene mesh per group (world space first) and material its triangles use, holding the
    // vertices its triangles index, in the file's material order; with the file's materials, one
    // scene material per file material its triangles use.
    std::map<std::pair<uint32_t, uint32_t>, TriangleMesh> parts;
    for (size_t t = 0; t < mesh.TriangleCount(); ++t) {
      const std::pair<uint32_t, uint32_t> key{keptGroups.empty() ? 0 : keptGroups[t],
                                              material < 0 ? keptMaterials[t] : 0};
      TriangleMesh& part = parts[key];
      part.indices.insert(part.indices.end(), mesh.indices.begin() + 3 * t,
                          mesh.indices.begin() + 3 * t + 3);
    }
    std::map<uint32_t, uint32_t> sceneMaterial;  // file material -> scene.materials
    size_t added = 0;
    for (auto& [key, part] : parts) {
      const auto [group, m] = key;
      if (group > 0 && groups[group - 1].empty()) continue;  // every placement dropped
      part.name = spec.name();
      if (material >= 0) {
        part.material = uint32_t(material);
      } else {
        auto it = sceneMaterial.find(m);
        if (it == sceneMaterial.end()) {
          Material fileMaterial = raw.materials[m].material;
          fileMaterial.name = path + ":" + fileMaterial.name;
          it = sceneMaterial.emplace(m, uint32_t(scene->materials.size())).first;
          scene->materials.push_back(std::move(fileMaterial));
        }
        part.material = it->second;
      }
      const Material& used = scene->materials[part.material];
      // The per-vertex values the material reads, beside the positions.
      const auto keep = [](bool wanted, const auto& all) {
        return wanted && !all.empty() ? &all : nullptr;
      };
      const auto* albedoUv = keep(bool(used.albedoMap.image), raw.albedoUv);
      const auto* emissionUv = keep(bool(used.emissionMap.image), raw.emissionUv);
      const auto* coverageUv = keep(bool(used.coverageMap.image), raw.coverageUv);
      const auto* colors = keep(used.vertexColors, raw.colors);
      std::vector<uint32_t> remap(mesh.positions.size(), UINT32_MAX);
      for (uint32_t& index : part.indices) {
        if (remap[index] == UINT32_MAX) {
          remap[index] = uint32_t(part.positions.size());
          part.positions.push_back(mesh.positions[index]);
          if (albedoUv) part.albedoUv.push_back((*albedoUv)[index]);
          if (emissionUv) part.emissionUv.push_back((*emissionUv)[index]);
          if (coverageUv) part.coverageUv.push_back((*coverageUv)[index]);
          if (colors) part.colors.push_back((*colors)[index]);
        }
        index = remap[index];
      }
      if (group > 0) {
        part.placements = groups[group - 1];
        // A light is sampled per triangle in world space: an emissive group is placed as copies.
        if (MaxComponent(used.emission) > 0 || used.emissionMap.image) {
          PB_ASSIGN_OR_RETURN(part, PlacedCopies(part, path));
        }
      }
      scene->meshes.push_back(std::move(part));
      ++added;
    }
    if (added == 0) return FieldError(path, "no triangle with a non-zero area");
    return absl::OkStatus();
  }

 private:
  const AssetSource& assets_;
  const JobLimits& limits_;
  int64_t jobLights_;
  MeshImportHandoff handoff_;
  std::vector<std::string> ignored_;

 public:
  const std::vector<std::string>& ignored() const { return ignored_; }

 private:
  int64_t triangles_ = 0;
};

absl::Status BuildEnvironment(const v1::Environment& spec, const AssetSource& assets,
                              const JobLimits& limits, v1::Environment* canonical,
                              Environment* env) {
  if (spec.has_uniform()) {
    const Vec3d radiance = ToVec3(spec.uniform().radiance());
    if (MaxComponent(radiance) > 0) {
      env->kind = Environment::Kind::kUniform;
      env->radiance = radiance;
    }
    return absl::OkStatus();
  }
  if (!spec.has_map()) return absl::OkStatus();
  const v1::EnvironmentMap& m = spec.map();
  const std::string path = "scene.environment.map";
  v1::EnvironmentMap* c = canonical->mutable_map();
  EnvironmentMap map;
  bool cube = false;
  // Files are read even with scale 0, so that a missing file is reported whatever the scale.
  if (m.faces_size() > 0) {  // validated: six faces, no file or blob
    std::array<EnvironmentMap, 6> faces;
    std::array<std::string, 6> facePaths;
    std::string faceDigests;
    for (int f = 0; f < 6; ++f) {
      const v1::EnvironmentFace& face = m.faces(f);
      const std::string facePath = job_internal::Index(path + ".faces", f);
      PB_ASSIGN_OR_RETURN(const std::string bytes,
                          ReadAsset(face.file(), &face.blob(), facePath, assets, limits));
      facePaths[size_t(f)] = facePath + (face.file().empty() ? ".blob" : ".file");
      PB_ASSIGN_OR_RETURN(
          job_internal::EnvironmentImage image,
          job_internal::DecodeEnvironmentImage(bytes, AssetName(face.file(), face.blob()),
                                               facePaths[size_t(f)], limits.maxEnvironmentPixels));
      faces[size_t(f)] = std::move(image.pixels);
      v1::EnvironmentFace* canonicalFace = c->mutable_faces(f);
      if (!face.file().empty()) *canonicalFace->mutable_blob() = DigestOf(bytes);
      canonicalFace->clear_file();
      faceDigests += Sha256Hex(bytes);
    }
    PB_ASSIGN_OR_RETURN(const EnvironmentMap stacked,
                        job_internal::StackCubeFaces(faces, facePaths));
    PB_ASSIGN_OR_RETURN(
        map, job_internal::LatLongFromCube(stacked, path + ".faces", limits.maxEnvironmentPixels));
    map.digest = Sha256Hex(faceDigests);
    cube = true;
  } else {
    PB_ASSIGN_OR_RETURN(const std::string bytes,
                        ReadAsset(m.file(), &m.blob(), path, assets, limits));
    const std::string fieldPath = path + (m.file().empty() ? ".blob" : ".file");
    PB_ASSIGN_OR_RETURN(
        job_internal::EnvironmentImage image,
        job_internal::DecodeEnvironmentImage(bytes, AssetName(m.file(), m.blob()), fieldPath,
                                             limits.maxEnvironmentPixels));
    cube = m.projection() == v1::EnvironmentMap::CUBE ||
           (m.projection() == v1::EnvironmentMap::PROJECTION_UNSPECIFIED && image.cubeTagged);
    if (cube) {
      PB_ASSIGN_OR_RETURN(
          map, job_internal::LatLongFromCube(image.pixels, fieldPath, limits.maxEnvironmentPixels));
    } else {
      map = std::move(image.pixels);
    }
    if (!m.file().empty()) *c->mutable_blob() = DigestOf(bytes);
    c->clear_file();
    map.digest = Sha256Hex(bytes);
  }
  // Canonical: the projection as read (lat-long spelled as the default, so that jobs written
  // before cube maps keep their digests).
  c->set_projection(cube ? v1::EnvironmentMap::CUBE : v1::EnvironmentMap::PROJECTION_UNSPECIFIED);

  map.scale = m.has_scale() ? m.scale() : 1;
  const float brightest =
      map.rgb.empty() ? 0.0f : *std::max_element(map.rgb.begin(), map.rgb.end());
  if (double(brightest) * map.scale > kMaxEmitted) {
    return FieldError(path + (m.has_scale()        ? ".scale"
                              : m.faces_size() > 0 ? ".faces"
                              : m.file().empty()   ? ".blob"
                                                   : ".file"),
                      "the brightest pixel (" + Num(brightest) + ") times the scale (" +
                          Num(map.scale) + ") is more than 1e30, " +
                          job_internal::kBeyondVolumeFloats);
  }
  map.worldFromMap = EnvironmentWorldFromMap(m.up(), m.rotation_deg());
  if (map.scale > 0) {
    env->kind = Environment::Kind::kMap;
    env->map = std::make_shared<const EnvironmentMap>(std::move(map));
  }
  return absl::OkStatus();
}

Light BuildLight(const v1::Light& l) {
  switch (l.kind_case()) {
    case v1::Light::kSpot: {
      const v1::SpotLight& s = l.spot();
      return SpotLight{ToVec3(s.position()), UnitVector(ToVec3(s.direction())),
                       ToVec3(s.intensity()), CosDegrees(s.inner_angle_deg()),
                       CosDegrees(s.outer_angle_deg())};
    }
    case v1::Light::kDirectional: {
      const v1::DirectionalLight& d = l.directional();
      return DirectionalLight{UnitVector(ToVec3(d.direction())), ToVec3(d.irradiance()),
                              CosDegrees(d.angular_diameter_deg() / 2)};
    }
    case v1::Light::kRect: {
      const v1::RectLight& r = l.rect();
      return RectLight{ToVec3(r.corner()), ToVec3(r.edge1()), ToVec3(r.edge2()),
                       ToVec3(r.radiance()), r.two_sided()};
    }
    case v1::Light::kDisk: {
      const v1::DiskLight& d = l.disk();
      return DiskLight{ToVec3(d.center()), UnitVector(ToVec3(d.normal())), d.radius(),
                       ToVec3(d.radiance()), d.two_sided()};
    }
    case v1::Light::kSphere: {
      const v1::SphereLight& s = l.sphere();
      return SphereLight{ToVec3(s.center()), s.radius(), ToVec3(s.radiance())};
    }
    case v1::Light::kPoint:
    default: {
      const v1::PointLight& p = l.point();
      return PointLight{ToVec3(p.position()), ToVec3(p.intensity())};
    }
  }
}

// Adds the finite extent of `light` (directional lights have none).
void AddLight(const Light& light, Box* box) {
  if (const auto* p = std::get_if<PointLight>(&light)) box->Add(p->position);
  if (const auto* s = std::get_if<SpotLight>(&light)) box->Add(s->position);
  if (const auto* r = std::get_if<RectLight>(&light)) {
    box->Add(r->corner);
    box->Add(r->corner + r->edge1);
    box->Add(r->corner + r->edge2);
    box->Add(r->corner + r->edge1 + r->edge2);
  }
  if (const auto* d = std::get_if<DiskLight>(&light)) {
    // A disk's extent along axis i is radius * sqrt(1 - n_i^2).
    Vec3d half;
    for (int i = 0; i < 3; ++i)
      half[i] = d->radius * std::sqrt(std::max(0.0, 1 - d->normal[i] * d->normal[i]));
    box->Add(d->center - half);
    box->Add(d->center + half);
  }
  if (const auto* s = std::get_if<SphereLight>(&light)) {
    box->Add(s->center - Vec3d(s->radius, s->radius, s->radius));
    box->Add(s->center + Vec3d(s->radius, s->radius, s->radius));
  }
}

// Refuses a scene whose finite parts span more than kMaxSceneSpan on an axis. Of the two parts
// holding its ends on the widest axis, it names the one farther from the median of the parts'
// centres (the outlier: a stray vertex, a light far away), the upper one on a tie.
absl::Status CheckSceneSpan(const Scene& scene) {
  std::vector<std::pair<std::string, Box>> parts;
  for (size_t i = 0; i < scene.meshes.size(); ++i) {
    Box b;
    GrowMeshBounds(scene.meshes[i], &b.lo, &b.hi);
    parts.emplace_back(Index("scene.meshes", int64_t(i)), b);
  }
  for (size_t i = 0; i < scene.lights.size(); ++i) {
    Box b;
    AddLight(scene.lights[i], &b);
    if (b.lo.x <= b.hi.x) parts.emplace_back(Index("scene.lights", int64_t(i)), b);  // finite
  }
  if (parts.empty()) return absl::OkStatus();
  Box all;
  for (const auto& [path, b] : parts) all.Add(b.lo), all.Add(b.hi);
  const Vec3d extent = all.hi - all.lo;
  const int axis =
      extent.x >= extent.y ? (extent.x >= extent.z ? 0 : 2) : (extent.y >= extent.z ? 1 : 2);
  if (extent[axis] <= kMaxSceneSpan) return absl::OkStatus();
  size_t low = 0, high = 0;
  std::vector<double> centres;
  for (size_t i = 0; i < parts.size(); ++i) {
    if (parts[i].second.lo[axis] < parts[low].second.lo[axis]) low = i;
    if (parts[i].second.hi[axis] > parts[high].second.hi[axis]) high = i;
    centres.push_back(0.5 * (parts[i].second.lo[axis] + parts[i].second.hi[axis]));
  }
  std::sort(centres.begin(), centres.end());
  const size_t n = centres.size();
  const double median = 0.5 * (centres[(n - 1) / 2] + centres[n / 2]);
  const bool highIsOut =
      parts[high].second.hi[axis] - median >= median - parts[low].second.lo[axis];
  const size_t out = highIsOut ? high : low, other = highIsOut ? low : high;
  const char* name = axis == 0 ? "x" : axis == 1 ? "y" : "z";
  const double at = highIsOut ? parts[out].second.hi[axis] : parts[out].second.lo[axis];
  const double otherEnd = highIsOut ? parts[other].second.lo[axis] : parts[other].second.hi[axis];
  return FieldError(parts[out].first,
                    "reaches " + std::string(name) + " = " + Num(at) + ", and " +
                        parts[other].first + " " + name + " = " + Num(otherEnd) +
                        ": the scene spans " + Num(extent[axis]) + ", more than the " +
                        Num(kMaxSceneSpan) +
                        " its single-precision tracer holds (move or drop the far part)");
}

bool AllZero(const google::protobuf::RepeatedField<double>& f) {
  return std::all_of(f.begin(), f.end(), [](double x) { return x == 0; });
}

bool IsIdentity(const google::protobuf::RepeatedField<double>& m) {
  for (int k = 0; k < m.size(); ++k)
    if (m[k] != (k % 5 == 0 ? 1.0 : 0.0)) return false;
  return true;
}

// Writes every field that holds its default the way an absent field does, so that jobs that bake
// the same way get the same digests whether or not they spell the defaults out: zero albedo and
// emission, an identity transform, a mesh's name (logs only), a map's scale 1 and up Y, a black
// environment, a medium with zero coefficients; the grid's default placement, a surface distance
// that only NEAR_SURFACES reads, and one spacing written as three equal numbers. `environmentKept`
// and `mediumKept` say whether the built scene has an environment and a medium.
void FoldDefaults(bool environmentKept, bool mediumKept, v1::Scene* scene, v1::Grid* grid) {
  for (v1::Material& m : *scene->mutable_materials()) {
    if (AllZero(m.albedo())) m.clear_albedo();
    if (AllZero(m.emission())) m.clear_emission();
  }
  for (v1::Mesh& m : *scene->mutable_meshes()) {
    m.clear_name();
    if (IsIdentity(m.transform())) m.clear_transform();
  }
  if (!environmentKept) {
    scene->clear_environment();
  } else if (scene->environment().has_map()) {
    v1::EnvironmentMap* map = scene->mutable_environment()->mutable_map();
    if (map->has_scale() && map->scale() == 1) map->clear_scale();
    if (map->up() == v1::EnvironmentMap::Y) map->set_up(v1::EnvironmentMap::UP_UNSPECIFIED);
  }
  if (!mediumKept) scene->clear_medium();

  if (grid->placement() == v1::Grid::OUTSIDE_GEOMETRY)
    grid->set_placement(v1::Grid::PLACEMENT_UNSPECIFIED);
  if (grid->placement() != v1::Grid::NEAR_SURFACES) grid->clear_surface_distance();
  if (grid->spacing().has_list_value()) {
    const auto& values = grid->spacing().list_value().values();
    if (values.size() == 3 && values[0].number_value() == values[1].number_value() &&
        values[0].number_value() == values[2].number_value()) {
      const double spacing = values[0].number_value();
      grid->mutable_spacing()->set_number_value(spacing);
    }
  }
}

}  // namespace

absl::StatusOr<Environment> LoadEnvironment(const v1::Environment& spec, const AssetSource& assets,
                                            const JobLimits& limits) {
  // Validated as a job's environment is, in a job of nothing else.
  v1::JobSpec job;
  *job.mutable_scene()->mutable_environment() = spec;
  for (int a = 0; a < 3; ++a) {
    job.mutable_grid()->add_min(0);
    job.mutable_grid()->add_max(0);
    job.mutable_grid()->add_counts(1);
  }
  PB_RETURN_IF_ERROR(ValidateJobSpec(job, limits));
  v1::Environment canonical;
  Environment env;
  PB_RETURN_IF_ERROR(BuildEnvironment(spec, assets, limits, &canonical, &env));
  return env;
}

absl::StatusOr<BakeJob> BuildBakeJob(const v1::JobSpec& spec, const AssetSource& assets,
                                     const JobLimits& limits) {
  return BuildBakeJob(spec, assets, limits, MeshImportHandoff());
}

absl::StatusOr<BakeJob> BuildBakeJob(const v1::JobSpec& spec, const AssetSource& assets,
                                     const JobLimits& limits, const MeshImportHandoff& handoff) {
  PB_RETURN_IF_ERROR(ValidateJobSpec(spec, limits));
  BakeJob job;
  job.settings = ResolveSettings(spec.settings());
  job.grid = ResolveGrid(spec.grid());
  const v1::Scene& scene = spec.scene();
  v1::Scene canonical = scene;
  Scene& out = job.scene;

  std::map<std::string, uint32_t> materialIndex;
  for (const v1::Material& m : scene.materials()) {
    materialIndex.emplace(m.name(), uint32_t(out.materials.size()));
    out.materials.push_back({m.name(), ToVec3(m.albedo()), ToVec3(m.emission())});
  }

  MeshBuilder meshes(assets, limits, scene.lights_size(), handoff);
  for (int i = 0; i < scene.meshes_size(); ++i) {
    const v1::Mesh& m = scene.meshes(i);
    const int64_t material = m.material().empty() ? -1 : int64_t(materialIndex.at(m.material()));
    PB_RETURN_IF_ERROR(meshes.Add(m, i, material, canonical.mutable_meshes(i), &out));
  }
  job.ignored = meshes.ignored();
  for (const v1::Light& l : scene.lights()) out.lights.push_back(BuildLight(l));
  PB_RETURN_IF_ERROR(CheckSceneSpan(out));
  PB_RETURN_IF_ERROR(BuildEnvironment(scene.environment(), assets, limits,
                                      canonical.mutable_environment(), &out.environment));
  if (!scene.has_environment()) canonical.clear_environment();

  if (scene.has_medium()) {
    const v1::Medium& m = scene.medium();
    Medium medium{ToVec3(m.sigma_a()), ToVec3(m.sigma_s()), m.g(), {}, {}};
    if (MaxComponent(medium.sigmaA) > 0 || MaxComponent(medium.sigmaS) > 0) {
      Box box;
      for (const TriangleMesh& mesh : out.meshes) GrowMeshBounds(mesh, &box.lo, &box.hi);
      for (const Light& light : out.lights) AddLight(light, &box);
      const ProbeGrid& g = job.grid;
      box.Add(g.origin);
      box.Add(g.Position(g.counts[0] - 1, g.counts[1] - 1, g.counts[2] - 1));
      box.Add(ToVec3(spec.grid().max()));
      const double pad =
          1e-4 * Length(box.hi - box.lo) +
          1e-6 * std::max(1.0, std::max(MaxComponent(Abs(box.lo)), MaxComponent(Abs(box.hi))));
      medium.boundsMin = box.lo - Vec3d(pad, pad, pad);
      medium.boundsMax = box.hi + Vec3d(pad, pad, pad);
      out.medium = medium;
    }
  }

  v1::Grid canonicalGrid = spec.grid();
  FoldDefaults(out.environment.kind != Environment::Kind::kNone, out.medium.has_value(), &canonical,
               &canonicalGrid);
  job.sceneDigest = Sha256Hex(DeterministicBytes(canonical));
  v1::JobSpec canonicalJob;
  *canonicalJob.mutable_scene() = std::move(canonical);
  *canonicalJob.mutable_grid() = std::move(canonicalGrid);
  *canonicalJob.mutable_settings() = SettingsToProto(job.settings);
  job.jobDigest = Sha256Hex(DeterministicBytes(canonicalJob) +
                            "\nprobebake-baker-version=" + std::to_string(kBakerVersion));
  job.settingsJson = SettingsToJson(job.settings);

  int64_t triangles = 0, placed = 0, instanced = 0;
  for (const TriangleMesh& mesh : out.meshes) {
    triangles += int64_t(mesh.TriangleCount());
    placed += int64_t(mesh.PlacedTriangleCount());
    instanced += !mesh.placements.empty();
  }
  Logger("job")->info(
      "job {}: {} meshes ({} instanced), {} triangles stored, {} placed, {} lights, {} probes, "
      "order {}",
      job.jobDigest.substr(0, 12), out.meshes.size(), instanced, triangles, placed,
      out.lights.size(), job.grid.ProbeCount(), job.settings.shOrder);
  return job;
}

absl::StatusOr<BakeJob> LoadBakeJob(const std::string& path, const JobLimits& limits) {
  return LoadBakeJob(path, limits, MeshImportHandoff());
}

absl::StatusOr<BakeJob> LoadBakeJob(const std::string& path, const JobLimits& limits,
                                    const MeshImportHandoff& handoff) {
  PB_ASSIGN_OR_RETURN(const v1::JobSpec spec, ReadJobFile(path));
  const LocalAssetSource assets(JobFileDir(path), "", limits.maxAssetBytes);
  absl::StatusOr<BakeJob> job = BuildBakeJob(spec, assets, limits, handoff);
  if (!job.ok()) return job_internal::PrefixLines(job.status(), path);
  return job;
}

}  // namespace probebake
