#include "imported_mesh_codec.h"

#include <map>
#include <memory>
#include <type_traits>

#include "probebake/base/byte_codec.h"

namespace probebake::job_internal {
namespace {

constexpr std::string_view kMagic = "PBMESH02";

// The smallest encoding of a texture, a material and a light: what a count of them must fit in.
constexpr uint64_t kMinTextureBytes = 8 + 4 + 4 + 1 + 8;
constexpr uint64_t kMinMaterialBytes = 8 + 6 * 8 + 3 * (8 + 3) + 1 + 2 * 8 + 1;
constexpr uint64_t kMinLightBytes = 1 + 2 * 3 * 8;

void PutVec(ByteWriter& out, const Vec3d& v) {
  out.Pod(v.x);
  out.Pod(v.y);
  out.Pod(v.z);
}

bool GetVec(ByteReader& in, Vec3d* v) {
  return in.Pod(&v->x) && in.Pod(&v->y) && in.Pod(&v->z);
}

void PutLight(ByteWriter& out, const Light& light) {
  out.Pod(uint8_t(light.index()));
  if (const auto* p = std::get_if<PointLight>(&light)) {
    PutVec(out, p->position);
    PutVec(out, p->intensity);
  } else if (const auto* s = std::get_if<SpotLight>(&light)) {
    PutVec(out, s->position);
    PutVec(out, s->direction);
    PutVec(out, s->intensity);
    out.Pod(s->cosInner);
    out.Pod(s->cosOuter);
  } else if (const auto* d = std::get_if<DirectionalLight>(&light)) {
    PutVec(out, d->direction);
    PutVec(out, d->irradiance);
    out.Pod(d->cosHalfAngle);
  } else if (const auto* r = std::get_if<RectLight>(&light)) {
    PutVec(out, r->corner);
    PutVec(out, r->edge1);
    PutVec(out, r->edge2);
    PutVec(out, r->radiance);
    out.Pod(uint8_t(r->twoSided));
  } else if (const auto* k = std::get_if<DiskLight>(&light)) {
    PutVec(out, k->center);
    PutVec(out, k->normal);
    out.Pod(k->radius);
    PutVec(out, k->radiance);
    out.Pod(uint8_t(k->twoSided));
  } else if (const auto* e = std::get_if<SphereLight>(&light)) {
    PutVec(out, e->center);
    out.Pod(e->radius);
    PutVec(out, e->radiance);
  }
}

bool GetBool(ByteReader& in, bool* value) {
  uint8_t byte = 0;
  if (!in.Pod(&byte) || byte > 1) return false;
  *value = byte == 1;
  return true;
}

bool GetLight(ByteReader& in, Light* light) {
  uint8_t kind = 0;
  if (!in.Pod(&kind)) return false;
  switch (kind) {
    case 0: {
      PointLight p;
      if (!GetVec(in, &p.position) || !GetVec(in, &p.intensity)) return false;
      *light = p;
      return true;
    }
    case 1: {
      SpotLight s;
      if (!GetVec(in, &s.position) || !GetVec(in, &s.direction) || !GetVec(in, &s.intensity) ||
          !in.Pod(&s.cosInner) || !in.Pod(&s.cosOuter))
        return false;
      *light = s;
      return true;
    }
    case 2: {
      DirectionalLight d;
      if (!GetVec(in, &d.direction) || !GetVec(in, &d.irradiance) || !in.Pod(&d.cosHalfAngle))
        return false;
      *light = d;
      return true;
    }
    case 3: {
      RectLight r;
      if (!GetVec(in, &r.corner) || !GetVec(in, &r.edge1) || !GetVec(in, &r.edge2) ||
          !GetVec(in, &r.radiance) || !GetBool(in, &r.twoSided))
        return false;
      *light = r;
      return true;
    }
    case 4: {
      DiskLight k;
      if (!GetVec(in, &k.center) || !GetVec(in, &k.normal) || !in.Pod(&k.radius) ||
          !GetVec(in, &k.radiance) || !GetBool(in, &k.twoSided))
        return false;
      *light = k;
      return true;
    }
    case 5: {
      SphereLight e;
      if (!GetVec(in, &e.center) || !in.Pod(&e.radius) || !GetVec(in, &e.radiance)) return false;
      *light = e;
      return true;
    }
    default:
      return false;
  }
}

static_assert(std::variant_size_v<Light> == 6, "GetLight/PutLight name every kind of light");

// The texture table of `materials`: each image once, in order of first use.
std::vector<std::shared_ptr<const Texture>> TextureTable(
    const std::vector<FileMaterial>& materials) {
  std::vector<std::shared_ptr<const Texture>> table;
  std::map<const Texture*, size_t> seen;
  for (const FileMaterial& file : materials) {
    for (const TextureMap* map :
         {&file.material.albedoMap, &file.material.emissionMap, &file.material.coverageMap}) {
      if (map->image && seen.emplace(map->image.get(), table.size()).second)
        table.push_back(map->image);
    }
  }
  return table;
}

}  // namespace

std::string EncodeImportedMesh(const ImportBinding& binding, const ImportedMesh& mesh) {
  ByteWriter out;
  out.bytes().append(kMagic);
  out.Pod(int32_t(binding.mesh));
  out.String(binding.sha256);
  out.String(binding.format);
  out.Pod(uint8_t(binding.fileMaterials));

  out.Pod(uint64_t(mesh.positions.size()));
  for (const Vec3d& p : mesh.positions) PutVec(out, p);
  out.Vector(mesh.indices);
  out.Vector(mesh.triangleMaterials);
  out.Vector(mesh.triangleGroups);
  out.Pod(uint64_t(mesh.groupPlacements.size()));
  for (const std::vector<MeshPlacement>& placements : mesh.groupPlacements) {
    out.Pod(uint64_t(placements.size()));
    for (const MeshPlacement& placement : placements) {
      for (int r = 0; r < 3; ++r) PutVec(out, placement.linear.Row(r));
      PutVec(out, placement.translation);
    }
  }

  const std::vector<std::shared_ptr<const Texture>> textures = TextureTable(mesh.materials);
  std::map<const Texture*, int64_t> textureIndex;
  out.Pod(uint64_t(textures.size()));
  for (const auto& texture : textures) {
    textureIndex.emplace(texture.get(), int64_t(textureIndex.size()));
    out.String(texture->name);
    out.Pod(int32_t(texture->width));
    out.Pod(int32_t(texture->height));
    out.Pod(uint8_t(texture->hasAlpha));
    out.Vector(texture->rgba);
  }
  out.Pod(uint64_t(mesh.materials.size()));
  for (const FileMaterial& file : mesh.materials) {
    const Material& m = file.material;
    out.String(m.name);
    PutVec(out, m.albedo);
    PutVec(out, m.emission);
    for (const TextureMap* map : {&m.albedoMap, &m.emissionMap, &m.coverageMap}) {
      out.Pod(map->image ? textureIndex.at(map->image.get()) : int64_t(-1));
      out.Pod(uint8_t(map->wrapX));
      out.Pod(uint8_t(map->wrapY));
      out.Pod(uint8_t(map->srgb));
    }
    out.Pod(uint8_t(m.vertexColors));
    out.Pod(m.coverage);
    out.Pod(m.alphaCutoff);
    out.Pod(uint8_t(m.doubleSided));
  }
  out.Vector(mesh.albedoUv);
  out.Vector(mesh.emissionUv);
  out.Vector(mesh.coverageUv);
  out.Vector(mesh.colors);

  out.Pod(uint64_t(mesh.lights.size()));
  for (const Light& light : mesh.lights) PutLight(out, light);
  out.Pod(uint64_t(mesh.ignoredExtensions.size()));
  for (const std::string& extension : mesh.ignoredExtensions) out.String(extension);
  out.Pod(uint64_t(mesh.referenceDigests.size()));
  for (const auto& [path, digest] : mesh.referenceDigests) {
    out.String(path);
    out.String(digest.sha256);
    out.Pod(digest.sizeBytes);
  }
  return std::move(out.bytes());
}

absl::StatusOr<ImportedMesh> DecodeImportedMesh(std::string_view entry,
                                                const ImportBinding& binding) {
  const std::string where =
      "mesh imports: the entry of scene.meshes[" + std::to_string(binding.mesh) + "]";
  const auto damaged = [&](const std::string& what) {
    return absl::InternalError(where + " is damaged (" + what + ")");
  };
  if (entry.substr(0, kMagic.size()) != kMagic) return damaged("no entry header");
  ByteReader in(entry.substr(kMagic.size()));
  ImportBinding bound;
  if (!in.Pod(&bound.mesh) || !in.String(&bound.sha256) || !in.String(&bound.format) ||
      !GetBool(in, &bound.fileMaterials))
    return damaged("its binding");
  if (bound.mesh != binding.mesh || bound.sha256 != binding.sha256 ||
      bound.format != binding.format || bound.fileMaterials != binding.fileMaterials) {
    return absl::InternalError(where + " was imported from other bytes, format or materials (" +
                               bound.format + " " + bound.sha256.substr(0, 12) + ", not " +
                               binding.format + " " + binding.sha256.substr(0, 12) + ")");
  }

  ImportedMesh mesh;
  uint64_t count = 0;
  if (!in.Count(3 * sizeof(double), &count)) return damaged("positions");
  mesh.positions.resize(size_t(count));
  for (Vec3d& p : mesh.positions)
    if (!GetVec(in, &p)) return damaged("positions");
  if (!in.Vector(&mesh.indices) || !in.Vector(&mesh.triangleMaterials) ||
      !in.Vector(&mesh.triangleGroups))
    return damaged("triangles");
  if (!in.Count(sizeof(uint64_t), &count)) return damaged("the groups");
  mesh.groupPlacements.resize(size_t(count));
  for (std::vector<MeshPlacement>& placements : mesh.groupPlacements) {
    if (!in.Count(4 * 3 * sizeof(double), &count) || count < 2) return damaged("a group");
    placements.resize(size_t(count));
    for (MeshPlacement& placement : placements) {
      Vec3d rows[3];
      for (Vec3d& row : rows)
        if (!GetVec(in, &row)) return damaged("a placement");
      if (!GetVec(in, &placement.translation)) return damaged("a placement");
      placement.linear = Mat3d::FromRows(rows[0], rows[1], rows[2]);
    }
  }
  if (!mesh.triangleGroups.empty() && mesh.triangleGroups.size() != mesh.indices.size() / 3)
    return damaged("a group per triangle");
  for (uint32_t group : mesh.triangleGroups)
    if (group > mesh.groupPlacements.size()) return damaged("a triangle's group");
  if (mesh.indices.size() % 3 != 0) return damaged("an index count not a multiple of 3");
  for (uint32_t index : mesh.indices)
    if (index >= mesh.positions.size()) return damaged("an index past the vertices");

  std::vector<std::shared_ptr<const Texture>> textures;
  if (!in.Count(kMinTextureBytes, &count)) return damaged("the texture count");
  for (uint64_t k = 0; k < count; ++k) {
    auto texture = std::make_shared<Texture>();
    int32_t width = 0, height = 0;
    if (!in.String(&texture->name) || !in.Pod(&width) || !in.Pod(&height) ||
        !GetBool(in, &texture->hasAlpha) || !in.Vector(&texture->rgba))
      return damaged("a texture");
    if (width <= 0 || height <= 0 || texture->rgba.size() != 4 * size_t(width) * size_t(height))
      return damaged("a texture's size");
    texture->width = width;
    texture->height = height;
    textures.push_back(std::move(texture));
  }
  if (!in.Count(kMinMaterialBytes, &count)) return damaged("the material count");
  mesh.materials.resize(size_t(count));
  for (FileMaterial& file : mesh.materials) {
    Material& m = file.material;
    if (!in.String(&m.name) || !GetVec(in, &m.albedo) || !GetVec(in, &m.emission))
      return damaged("a material");
    for (TextureMap* map : {&m.albedoMap, &m.emissionMap, &m.coverageMap}) {
      int64_t texture = 0;
      uint8_t wrapX = 0, wrapY = 0;
      if (!in.Pod(&texture) || !in.Pod(&wrapX) || !in.Pod(&wrapY) || !GetBool(in, &map->srgb))
        return damaged("a material's map");
      if (texture < -1 || texture >= int64_t(textures.size()) ||
          wrapX > uint8_t(TextureWrap::kMirror) || wrapY > uint8_t(TextureWrap::kMirror))
        return damaged("a material's map");
      if (texture >= 0) map->image = textures[size_t(texture)];
      map->wrapX = TextureWrap(wrapX);
      map->wrapY = TextureWrap(wrapY);
    }
    if (!GetBool(in, &m.vertexColors) || !in.Pod(&m.coverage) || !in.Pod(&m.alphaCutoff) ||
        !GetBool(in, &m.doubleSided))
      return damaged("a material");
  }
  // The file's materials are read per triangle; without them the table may be left out.
  if (mesh.triangleMaterials.size() != mesh.indices.size() / 3 &&
      (binding.fileMaterials || !mesh.triangleMaterials.empty()))
    return damaged("a material per triangle");
  for (uint32_t material : mesh.triangleMaterials)
    if (material >= mesh.materials.size()) return damaged("a triangle's material");

  if (!in.Vector(&mesh.albedoUv) || !in.Vector(&mesh.emissionUv) || !in.Vector(&mesh.coverageUv) ||
      !in.Vector(&mesh.colors))
    return damaged("the per-vertex values");
  for (size_t size :
       {mesh.albedoUv.size(), mesh.emissionUv.size(), mesh.coverageUv.size(), mesh.colors.size()}) {
    if (size != 0 && size != mesh.positions.size()) return damaged("a per-vertex array's size");
  }

  if (!in.Count(kMinLightBytes, &count)) return damaged("the light count");
  mesh.lights.resize(size_t(count));
  for (Light& light : mesh.lights)
    if (!GetLight(in, &light)) return damaged("a light");
  if (!in.Count(sizeof(uint64_t), &count)) return damaged("the ignored extensions");
  mesh.ignoredExtensions.resize(size_t(count));
  for (std::string& extension : mesh.ignoredExtensions)
    if (!in.String(&extension)) return damaged("the ignored extensions");
  if (!in.Count(3 * sizeof(uint64_t), &count)) return damaged("the referenced files");
  for (uint64_t k = 0; k < count; ++k) {
    std::string path;
    ImportedMesh::FileDigest digest;
    if (!in.String(&path) || !in.String(&digest.sha256) || !in.Pod(&digest.sizeBytes))
      return damaged("the referenced files");
    mesh.referenceDigests.emplace(std::move(path), std::move(digest));
  }
  if (!in.AtEnd()) return damaged("bytes after its end");
  return mesh;
}

}  // namespace probebake::job_internal
