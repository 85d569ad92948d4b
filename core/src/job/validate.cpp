#include "probebake/job/validate.h"

#include <google/protobuf/struct.pb.h>

#include <cfloat>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <string>

#include "errors.h"
#include "grid_internal.h"
#include "probebake/job/digest.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/job.h"
#include "probebake/math/vec3.h"
#include "text.h"

namespace probebake {
namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::Reflection;
using google::protobuf::RepeatedField;
using google::protobuf::Value;
using job_internal::ErrorList;
using job_internal::Index;
using job_internal::Member;
using job_internal::Num;
using job_internal::Quoted;

using Doubles = RepeatedField<double>;

// A limit of 0 means "no limit".
bool Above(double value, double limit) {
  return limit > 0 && value > limit;
}

bool AllFinite(const Doubles& values) {
  for (double x : values)
    if (!std::isfinite(x)) return false;
  return true;
}

std::string TooBright(double value) {
  return Num(value) + " is more than 1e30, " + job_internal::kBeyondVolumeFloats;
}

// Largest |component|, for scale-free tests on vectors whose length could under- or overflow.
double MaxAbs(const Vec3d& v) {
  return MaxComponent(Abs(v));
}

class Validator {
 public:
  explicit Validator(const JobLimits& limits) : limits_(limits) {}

  absl::Status Run(const v1::JobSpec& job) {
    NonFinite(job, "");
    Scene(job.scene());
    if (!job.has_grid()) {
      errors_.Add("grid", "missing");
    } else {
      Grid(job.grid());
      if (errors_.ok()) {
        const ProbeGrid resolved = ResolveGrid(job.grid());
        VoxelVolume(resolved);
        if (errors_.ok()) SpacingPrecision(resolved, job_internal::HasSpacing(job.grid()));
      }
      // Known up front to bake nothing: no surface for NEAR_SURFACES to be near.
      if (job.grid().placement() == v1::Grid::NEAR_SURFACES && job.scene().meshes().empty()) {
        errors_.Add("grid.placement",
                    "NEAR_SURFACES keeps the probes near mesh surfaces, and the scene has no "
                    "meshes: every probe would be left out (use ALL)");
      }
    }
    Settings(job.settings());
    return errors_.ToStatus();
  }

 private:
  // ---- Every number finite (the value checks below skip non-finite numbers) ----

  void NonFiniteNumber(double x, const std::string& path) {
    if (std::isnan(x)) errors_.Add(path, "NaN is not allowed (numbers must be finite)");
    if (std::isinf(x)) errors_.Add(path, "infinity is not allowed (numbers must be finite)");
  }

  void NonFiniteValue(const Value& v, const std::string& path) {
    if (v.kind_case() == Value::kNumberValue) NonFiniteNumber(v.number_value(), path);
    if (v.kind_case() == Value::kListValue) {
      for (int i = 0; i < v.list_value().values_size(); ++i)
        NonFiniteValue(v.list_value().values(i), Index(path, i));
    }
    if (v.kind_case() == Value::kStructValue) {
      for (const auto& [key, child] : v.struct_value().fields())
        NonFiniteValue(child, Member(path, key));
    }
  }

  void NonFinite(const Message& message, const std::string& path) {
    const Reflection* reflection = message.GetReflection();
    std::vector<const FieldDescriptor*> fields;
    reflection->ListFields(message, &fields);
    for (const FieldDescriptor* field : fields) {
      const std::string fieldPath = Member(path, field->json_name());
      const bool repeated = field->is_repeated();
      const int n = repeated ? reflection->FieldSize(message, field) : 1;
      for (int i = 0; i < n; ++i) {
        const std::string p = repeated ? Index(fieldPath, i) : fieldPath;
        switch (field->cpp_type()) {
          case FieldDescriptor::CPPTYPE_DOUBLE:
            NonFiniteNumber(repeated ? reflection->GetRepeatedDouble(message, field, i)
                                     : reflection->GetDouble(message, field),
                            p);
            break;
          case FieldDescriptor::CPPTYPE_FLOAT:
            NonFiniteNumber(repeated ? reflection->GetRepeatedFloat(message, field, i)
                                     : reflection->GetFloat(message, field),
                            p);
            break;
          case FieldDescriptor::CPPTYPE_MESSAGE: {
            const Message& child = repeated ? reflection->GetRepeatedMessage(message, field, i)
                                            : reflection->GetMessage(message, field);
            if (field->message_type() == Value::descriptor()) {
              NonFiniteValue(static_cast<const Value&>(child), p);
            } else {
              NonFinite(child, p);
            }
            break;
          }
          default:
            break;
        }
      }
    }
  }

  // ---- Vectors ----

  // A 3-vector; absent is an error when `required`. nullopt when absent, of the wrong length or
  // not finite (reported by NonFinite).
  std::optional<Vec3d> Vec3(const Doubles& f, const std::string& path, bool required) {
    if (f.empty()) {
      if (required) errors_.Add(path, "missing (expected 3 numbers)");
      return std::nullopt;
    }
    if (f.size() != 3) {
      errors_.Add(path, "expected 3 numbers, got " + Num(f.size()));
      return std::nullopt;
    }
    if (!AllFinite(f)) return std::nullopt;
    return Vec3d(f[0], f[1], f[2]);
  }

  // Radiance, intensity, irradiance, emission, medium coefficients: each channel >= 0; what a
  // light emits also at most kMaxEmitted.
  void NonNegativeRgb(const Doubles& f, const std::string& path, bool required,
                      bool emitted = false) {
    const std::optional<Vec3d> v = Vec3(f, path, required);
    if (!v) return;
    for (int c = 0; c < 3; ++c) {
      if ((*v)[c] < 0) errors_.Add(Index(path, c), "negative (" + Num((*v)[c]) + ")");
      if (emitted && (*v)[c] > kMaxEmitted) errors_.Add(Index(path, c), TooBright((*v)[c]));
    }
  }

  // A direction or normal: non-zero. Returns it when valid.
  std::optional<Vec3d> Direction(const Doubles& f, const std::string& path) {
    const std::optional<Vec3d> v = Vec3(f, path, true);
    if (v && MaxAbs(*v) == 0) {
      errors_.Add(path, "zero length");
      return std::nullopt;
    }
    return v;
  }

  // A radius > 0 whose disk area neither underflows nor overflows.
  void Radius(double r, const std::string& path) {
    if (!std::isfinite(r)) return;
    if (!(r > 0)) {
      errors_.Add(path, "must be > 0 (got " + Num(r) + ")");
    } else if (!(r * r >= DBL_MIN)) {
      errors_.Add(path, "too small (" + Num(r) + ": its area underflows)");
    } else if (!std::isfinite(r * r * 4 * M_PI)) {
      errors_.Add(path, "too large (" + Num(r) + ": its area overflows)");
    }
  }

  // ---- Assets ----

  void RelativePath(const std::string& file, const std::string& path) {
    if (std::filesystem::path(file).is_absolute())
      errors_.Add(path, Quoted(file) + " must be a path relative to the job file");
  }

  void BlobDigest(const v1::Digest& digest, const std::string& path) {
    if (!IsSha256Hex(digest.hash()))
      errors_.Add(path + ".hash", "expected 64 lowercase hex digits (SHA-256)");
    if (digest.size_bytes() < 0) {
      errors_.Add(path + ".sizeBytes", "negative (" + Num(digest.size_bytes()) + ")");
    } else if (Above(double(digest.size_bytes()), double(limits_.maxAssetBytes))) {
      errors_.Add(path + ".sizeBytes", Num(digest.size_bytes()) + " bytes, above the limit of " +
                                           Num(limits_.maxAssetBytes));
    }
  }

  // ---- Scene ----

  void Scene(const v1::Scene& scene) {
    std::map<std::string, int> materialIndex;
    for (int i = 0; i < scene.materials_size(); ++i) {
      const v1::Material& m = scene.materials(i);
      const std::string path = Index("scene.materials", i);
      if (m.name().empty()) {
        errors_.Add(path + ".name", "missing");
      } else if (const auto [it, inserted] = materialIndex.emplace(m.name(), i); !inserted) {
        errors_.Add(path + ".name", "duplicate name " + Quoted(m.name()) + " (also " +
                                        Index("scene.materials", it->second) + ")");
      }
      if (const std::optional<Vec3d> albedo = Vec3(m.albedo(), path + ".albedo", false)) {
        for (int c = 0; c < 3; ++c) {
          const double a = (*albedo)[c];
          if (!(a >= 0 && a < 1))
            errors_.Add(Index(path + ".albedo", c), Num(a) + " is outside [0, 1)");
        }
      }
      NonNegativeRgb(m.emission(), path + ".emission", false, true);
    }

    int64_t inlineTriangles = 0;
    bool triangleLimitReported = false;
    for (int i = 0; i < scene.meshes_size(); ++i) {
      const v1::Mesh& mesh = scene.meshes(i);
      const std::string path = Index("scene.meshes", i);
      Mesh(mesh, path, materialIndex);
      if (mesh.file().empty() && !mesh.has_blob()) {
        inlineTriangles += mesh.indices_size() / 3;
        if (!triangleLimitReported &&
            Above(double(inlineTriangles), double(limits_.maxTriangles))) {
          errors_.Add(path + ".indices", "the scene's inline triangles reach " +
                                             Num(inlineTriangles) + " here, above the limit of " +
                                             Num(limits_.maxTriangles));
          triangleLimitReported = true;
        }
      }
    }

    if (Above(scene.lights_size(), limits_.maxLights)) {
      errors_.Add("scene.lights", Num(scene.lights_size()) + " lights, above the limit of " +
                                      Num(limits_.maxLights));
    }
    for (int i = 0; i < scene.lights_size(); ++i) Light(scene.lights(i), Index("scene.lights", i));

    if (scene.has_environment()) Environment(scene.environment());
    if (scene.has_medium()) {
      const v1::Medium& medium = scene.medium();
      NonNegativeRgb(medium.sigma_a(), "scene.medium.sigmaA", true);
      NonNegativeRgb(medium.sigma_s(), "scene.medium.sigmaS", true);
      if (std::isfinite(medium.g()) && !(std::abs(medium.g()) < 1))
        errors_.Add("scene.medium.g", "must be in (-1, 1) (got " + Num(medium.g()) + ")");
    }
  }

  void Mesh(const v1::Mesh& mesh, const std::string& path,
            const std::map<std::string, int>& materialIndex) {
    const bool hasFile = !mesh.file().empty();
    const bool hasBlob = mesh.has_blob();
    const bool hasInline = mesh.positions_size() > 0;
    const int sources = int(hasFile) + int(hasBlob) + int(hasInline);
    if (sources == 0) {
      errors_.Add(path, "no geometry (expected one of file, blob or positions)");
    } else if (sources > 1) {
      errors_.Add(path, "more than one of file, blob and positions given");
    }

    if (hasFile) {
      RelativePath(mesh.file(), path + ".file");
      if (!MeshFormatOf(mesh)) {
        if (mesh.format().empty()) {
          errors_.Add(path + ".file", "unknown mesh format of " + Quoted(mesh.file()) +
                                          " (expected .obj, .ply, .gltf or .glb, or a format)");
        }
      }
    }
    if (mesh.references_size() > 0 && !hasBlob) {
      errors_.Add(path + ".references",
                  "only used with blob (a file's references are read beside it)");
    }
    for (const auto& [modelPath, digest] : mesh.references()) {
      const std::string field = path + ".references[" + Quoted(modelPath) + "]";
      if (modelPath.empty() || modelPath != NormalizeModelPath(modelPath))
        errors_.Add(field, "not a normalized path (expected " +
                               Quoted(NormalizeModelPath(modelPath)) + ")");
      BlobDigest(digest, field);
    }
    if (hasBlob) {
      BlobDigest(mesh.blob(), path + ".blob");
      if (mesh.format().empty())
        errors_.Add(path + ".format", "required with blob (obj, ply, gltf or glb)");
    }
    if (!mesh.format().empty() && !MeshFormatOf(mesh)) {
      errors_.Add(path + ".format",
                  "unknown format " + Quoted(mesh.format()) + " (expected obj, ply, gltf or glb)");
    }
    if (!mesh.format().empty() && !hasFile && !hasBlob) {
      errors_.Add(path + ".format", "only used with file or blob");
    }

    if (hasInline) {
      const int64_t vertices = mesh.positions_size() / 3;
      if (mesh.positions_size() % 3 != 0) {
        errors_.Add(path + ".positions",
                    "length " + Num(mesh.positions_size()) + " is not a multiple of 3");
      }
      if (mesh.indices_size() == 0) {
        errors_.Add(path + ".indices", "missing (three vertex indices per triangle)");
      } else if (mesh.indices_size() % 3 != 0) {
        errors_.Add(path + ".indices",
                    "length " + Num(mesh.indices_size()) + " is not a multiple of 3");
      }
      for (int k = 0; k < mesh.indices_size(); ++k) {
        if (int64_t(mesh.indices(k)) >= vertices) {
          // One report per mesh: a shifted index buffer would otherwise flood the message.
          errors_.Add(Index(path + ".indices", k),
                      Num(mesh.indices(k)) + " is out of range (" + Num(vertices) + " vertices)");
          break;
        }
      }
    } else if (mesh.indices_size() > 0) {
      errors_.Add(path + ".indices", "only used with positions");
    }

    if (mesh.material().empty()) {
      // A model file brings its own materials; inline triangles have none.
      if (hasInline)
        errors_.Add(path + ".material", "missing (the name of a material in scene.materials)");
    } else if (!materialIndex.contains(mesh.material())) {
      errors_.Add(path + ".material", "unknown material " + Quoted(mesh.material()));
    }

    Transform(mesh.transform(), path + ".transform");
  }

  void Transform(const Doubles& t, const std::string& path) {
    if (t.empty()) return;  // identity
    if (t.size() != 16) {
      errors_.Add(path, "expected 16 numbers (4x4, row-major), got " + Num(t.size()));
      return;
    }
    if (!AllFinite(t)) return;
    if (t[12] != 0 || t[13] != 0 || t[14] != 0 || t[15] != 1) {
      errors_.Add(path, "the last row must be (0, 0, 0, 1), got (" + Num(t[12]) + ", " +
                            Num(t[13]) + ", " + Num(t[14]) + ", " + Num(t[15]) + ")");
    }
    // Singular when the rows, scaled to unit length, span (almost) no volume: scale-free, so a
    // uniform scale of 1e-6 is fine but a flattening one is not.
    Vec3d rows[3];
    for (int r = 0; r < 3; ++r) {
      rows[r] = Vec3d(t[4 * r], t[4 * r + 1], t[4 * r + 2]);
      const double m = MaxAbs(rows[r]);
      if (m == 0) {
        errors_.Add(path, "singular (row " + Num(r) + " of the 3x3 part is zero)");
        return;
      }
      rows[r] = Normalize(rows[r] / m);
    }
    const double volume = std::abs(Dot(rows[0], Cross(rows[1], rows[2])));
    if (!(volume > 1e-12)) {
      errors_.Add(path, "singular (the 3x3 part has no inverse)");
    }
  }

  void Light(const v1::Light& light, const std::string& path) {
    switch (light.kind_case()) {
      case v1::Light::KIND_NOT_SET:
        errors_.Add(path,
                    "no light kind (expected one of point, spot, directional, rect, disk, "
                    "sphere)");
        return;
      case v1::Light::kPoint: {
        const std::string p = path + ".point";
        Vec3(light.point().position(), p + ".position", true);
        NonNegativeRgb(light.point().intensity(), p + ".intensity", true, true);
        return;
      }
      case v1::Light::kSpot: {
        const v1::SpotLight& spot = light.spot();
        const std::string p = path + ".spot";
        Vec3(spot.position(), p + ".position", true);
        Direction(spot.direction(), p + ".direction");
        NonNegativeRgb(spot.intensity(), p + ".intensity", true, true);
        const double inner = spot.inner_angle_deg(), outer = spot.outer_angle_deg();
        if (!std::isfinite(inner) || !std::isfinite(outer)) return;
        if (!(inner >= 0 && inner <= 180))
          errors_.Add(p + ".innerAngleDeg", "must be in [0, 180] (got " + Num(inner) + ")");
        if (!(outer > 0 && outer <= 180))
          errors_.Add(p + ".outerAngleDeg", "must be in (0, 180] (got " + Num(outer) + ")");
        if (inner > outer) {
          errors_.Add(p + ".innerAngleDeg",
                      "greater than outerAngleDeg (" + Num(inner) + " > " + Num(outer) + ")");
        }
        return;
      }
      case v1::Light::kDirectional: {
        const v1::DirectionalLight& d = light.directional();
        const std::string p = path + ".directional";
        Direction(d.direction(), p + ".direction");
        NonNegativeRgb(d.irradiance(), p + ".irradiance", true, true);
        const double a = d.angular_diameter_deg();
        if (std::isfinite(a) && !(a >= 0 && a < 180))
          errors_.Add(p + ".angularDiameterDeg", "must be in [0, 180) (got " + Num(a) + ")");
        return;
      }
      case v1::Light::kRect: {
        const v1::RectLight& rect = light.rect();
        const std::string p = path + ".rect";
        Vec3(rect.corner(), p + ".corner", true);
        const std::optional<Vec3d> e1 = Direction(rect.edge1(), p + ".edge1");
        const std::optional<Vec3d> e2 = Direction(rect.edge2(), p + ".edge2");
        NonNegativeRgb(rect.radiance(), p + ".radiance", true, true);
        if (e1 && e2) {
          const Vec3d a = Normalize(*e1 / MaxAbs(*e1)), b = Normalize(*e2 / MaxAbs(*e2));
          const double area = Length(Cross(*e1, *e2));
          if (!(Length(Cross(a, b)) > 1e-12)) {
            errors_.Add(p + ".edge2", "parallel to edge1 (zero area)");
          } else if (!(area >= DBL_MIN)) {
            errors_.Add(p, "zero area (the edges' cross product underflows)");
          } else if (!std::isfinite(area)) {
            errors_.Add(p, "area too large (the edges' cross product overflows)");
          }
        }
        return;
      }
      case v1::Light::kDisk: {
        const v1::DiskLight& disk = light.disk();
        const std::string p = path + ".disk";
        Vec3(disk.center(), p + ".center", true);
        Direction(disk.normal(), p + ".normal");
        Radius(disk.radius(), p + ".radius");
        NonNegativeRgb(disk.radiance(), p + ".radiance", true, true);
        return;
      }
      case v1::Light::kSphere: {
        const v1::SphereLight& sphere = light.sphere();
        const std::string p = path + ".sphere";
        Vec3(sphere.center(), p + ".center", true);
        Radius(sphere.radius(), p + ".radius");
        NonNegativeRgb(sphere.radiance(), p + ".radiance", true, true);
        return;
      }
    }
  }

  void Environment(const v1::Environment& env) {
    switch (env.kind_case()) {
      case v1::Environment::KIND_NOT_SET:
        errors_.Add("scene.environment", "expected one of uniform or map");
        return;
      case v1::Environment::kUniform:
        NonNegativeRgb(env.uniform().radiance(), "scene.environment.uniform.radiance", true, true);
        return;
      case v1::Environment::kMap: {
        const v1::EnvironmentMap& map = env.map();
        const std::string p = "scene.environment.map";
        const bool hasFile = !map.file().empty();
        if (map.faces_size() > 0) {
          if (hasFile || map.has_blob()) {
            errors_.Add(p, "give file or blob, or faces, not both");
          }
          if (map.faces_size() != 6) {
            errors_.Add(p + ".faces",
                        "expected 6 faces (+X, -X, +Y, -Y, +Z, -Z), got " + Num(map.faces_size()));
          }
          if (map.projection() != v1::EnvironmentMap::CUBE &&
              map.projection() != v1::EnvironmentMap::PROJECTION_UNSPECIFIED) {
            errors_.Add(p + ".projection", "faces make a cube map: projection must be CUBE");
          }
          for (int f = 0; f < map.faces_size(); ++f) {
            const v1::EnvironmentFace& face = map.faces(f);
            const std::string fp = Index(p + ".faces", f);
            const bool faceFile = !face.file().empty();
            if (faceFile == face.has_blob()) {
              errors_.Add(fp, faceFile ? "give file or blob, not both" : "missing file or blob");
            }
            if (faceFile) RelativePath(face.file(), fp + ".file");
            if (face.has_blob()) BlobDigest(face.blob(), fp + ".blob");
          }
        } else if (hasFile == map.has_blob()) {
          errors_.Add(p, hasFile ? "give file or blob, not both" : "missing file, blob or faces");
        }
        if (hasFile) RelativePath(map.file(), p + ".file");
        if (map.has_blob()) BlobDigest(map.blob(), p + ".blob");
        if (!v1::EnvironmentMap::Projection_IsValid(map.projection())) {
          errors_.Add(p + ".projection", "unknown value " + Num(int(map.projection())) +
                                             " (expected LAT_LONG or CUBE)");
        }
        if (map.has_scale() && std::isfinite(map.scale()) && map.scale() < 0)
          errors_.Add(p + ".scale", "negative (" + Num(map.scale()) + ")");
        if (map.has_scale() && std::isfinite(map.scale()) && map.scale() > kMaxEmitted)
          errors_.Add(p + ".scale", TooBright(map.scale()));
        if (!v1::EnvironmentMap::Up_IsValid(map.up()))
          errors_.Add(p + ".up", "unknown value " + Num(int(map.up())) + " (expected Y or Z)");
        return;
      }
    }
  }

  // ---- Grid ----

  void Grid(const v1::Grid& grid) {
    const std::optional<Vec3d> lo = Vec3(grid.min(), "grid.min", true);
    const std::optional<Vec3d> hi = Vec3(grid.max(), "grid.max", true);
    bool ordered = lo && hi;
    if (ordered) {
      for (int a = 0; a < 3; ++a) {
        if ((*hi)[a] < (*lo)[a]) {
          errors_.Add(Index("grid.max", a), "less than " + Index("grid.min", a) + " (" +
                                                Num((*hi)[a]) + " < " + Num((*lo)[a]) + ")");
          ordered = false;
        }
      }
    }

    const bool hasCounts = grid.counts_size() > 0;
    const bool hasSpacing = job_internal::HasSpacing(grid);
    if (hasCounts && hasSpacing) errors_.Add("grid", "give counts or spacing, not both");
    if (!hasCounts && !hasSpacing) errors_.Add("grid", "missing counts or spacing (no probes)");

    if (hasCounts) {
      if (grid.counts_size() != 3) {
        errors_.Add("grid.counts", "expected 3 integers, got " + Num(grid.counts_size()));
      } else {
        bool countsOk = true;
        double probes = 1;
        for (int a = 0; a < 3; ++a) {
          const int n = grid.counts(a);
          if (n < 1) {
            errors_.Add(Index("grid.counts", a), "must be >= 1 (got " + Num(n) + ")");
            countsOk = false;
          } else if (ordered && n > 1 && (*lo)[a] == (*hi)[a]) {
            errors_.Add(Index("grid.counts", a), Num(n) + " probes on an axis of zero extent (" +
                                                     Index("grid.min", a) +
                                                     " == " + Index("grid.max", a) + ")");
          }
          probes *= n;
        }
        if (countsOk) ProbeLimit(probes, "grid.counts");
      }
    }

    if (hasSpacing) {
      Vec3d spacing;
      if (Spacing(grid.spacing(), &spacing) && ordered) {
        double probes = 1;
        for (int a = 0; a < 3; ++a) {
          const double n = job_internal::ProbesOnAxis((*lo)[a], (*hi)[a], spacing[a]);
          if (!(n <= double(std::numeric_limits<int32_t>::max()))) {
            errors_.Add(Index("grid.spacing", a),
                        "too fine: " + Num(n) + " probes on axis " + Num(a));
            return;
          }
          probes *= n;
        }
        ProbeLimit(probes, "grid.spacing");
      }
    }

    const double distance = grid.surface_distance();
    if (!v1::Grid::Placement_IsValid(grid.placement())) {
      errors_.Add("grid.placement", "unknown value " + Num(int(grid.placement())) +
                                        " (expected ALL, OUTSIDE_GEOMETRY or NEAR_SURFACES)");
    } else if (grid.placement() == v1::Grid::NEAR_SURFACES) {
      if (std::isfinite(distance) && !(distance > 0)) {
        errors_.Add("grid.surfaceDistance",
                    "must be > 0 with placement NEAR_SURFACES (got " + Num(distance) + ")");
      }
    } else if (std::isfinite(distance) && distance < 0) {
      errors_.Add("grid.surfaceDistance", "negative (" + Num(distance) + ")");
    }
  }

  // OpenVDB refuses a transform whose voxel volume, the product of the three spacings, is below
  // 3e-15 (ScaleMap's 3 x Tolerance<double>): a spacing of 1e-5 on every axis baked in full, then
  // failed to write.
  void VoxelVolume(const ProbeGrid& g) {
    const double volume = g.spacing.x * g.spacing.y * g.spacing.z;
    if (!IsFinite(g.spacing) || !std::isfinite(volume)) {
      errors_.Add("grid", "probe spacing (" + Num(g.spacing.x) + ", " + Num(g.spacing.y) + ", " +
                              Num(g.spacing.z) + ") overflows: max - min is too large");
    } else if (!(volume >= 3e-15)) {
      errors_.Add("grid", "probe spacing (" + Num(g.spacing.x) + ", " + Num(g.spacing.y) + ", " +
                              Num(g.spacing.z) +
                              ") is too fine for an OpenVDB grid, whose voxel volume (the "
                              "product of the three spacings) must be at least 3e-15");
    }
  }

  // A spacing must be at least 2^-44 of the coordinates on its axis, 256 ulps of their double:
  // probe positions are then exact to 1/256 of a spacing, and the count a spacing gives cannot gain
  // a probe past max from rounding (grid_internal.h: its tolerance stays under 2^-5 of one). At
  // 1e12 with spacing 0.001 (8 ulps) the count gained a probe past max; at 1e14 OpenVDB refused
  // the transform after the bake.
  void SpacingPrecision(const ProbeGrid& g, bool hasSpacing) {
    constexpr double kMinRelativeSpacing = 0x1p-44;
    for (int a = 0; a < 3; ++a) {
      const double last = g.origin[a] + g.spacing[a] * (g.counts[a] - 1);
      const double magnitude = std::max(std::abs(g.origin[a]), std::abs(last));
      if (g.spacing[a] >= kMinRelativeSpacing * magnitude) continue;
      errors_.Add(Index(hasSpacing ? "grid.spacing" : "grid.counts", a),
                  "probe spacing " + Num(g.spacing[a]) + " is too fine for coordinates of " +
                      Num(magnitude) + ": double precision needs at least " +
                      Num(kMinRelativeSpacing * magnitude) + " there (2^-44 of them)");
    }
  }

  // Spacing: a number or 3 numbers, each > 0. False when invalid (reported) or not finite.
  bool Spacing(const Value& v, Vec3d* spacing) {
    const std::string path = "grid.spacing";
    auto positive = [&](const Value& x, const std::string& p, double* out) {
      if (x.kind_case() != Value::kNumberValue) {
        errors_.Add(p, "expected a number");
        return false;
      }
      *out = x.number_value();
      if (!std::isfinite(*out)) return false;
      if (!(*out > 0)) {
        errors_.Add(p, "must be > 0 (got " + Num(*out) + ")");
        return false;
      }
      return true;
    };
    if (v.kind_case() == Value::kNumberValue) {
      double s = 0;
      if (!positive(v, path, &s)) return false;
      *spacing = Vec3d(s, s, s);
      return true;
    }
    if (v.kind_case() == Value::kListValue && v.list_value().values_size() == 3) {
      bool ok = true;
      for (int a = 0; a < 3; ++a)
        ok &= positive(v.list_value().values(a), Index(path, a), &(*spacing)[a]);
      return ok;
    }
    errors_.Add(path, "expected a number or 3 numbers");
    return false;
  }

  void ProbeLimit(double probes, const std::string& path) {
    if (Above(probes, double(limits_.maxProbes))) {
      errors_.Add(path, Num(probes) + " probes, above the limit of " + Num(limits_.maxProbes));
    }
  }

  // ---- Settings ----

  void Settings(const v1::BakeSettings& s) {
    const std::string p = "settings";
    if (!s.has_sh_order()) {
      // A server's limits hold for what the job leaves to the defaults too.
      if (Above(kDefaultShOrder, limits_.maxShOrder)) {
        errors_.Add(p + ".shOrder (default)", Num(kDefaultShOrder) + " is above the limit of " +
                                                  Num(limits_.maxShOrder) + ": give a lower one");
      }
    } else {
      const int order = s.sh_order();
      if (order < 0) {
        errors_.Add(p + ".shOrder", "must be >= 0 (got " + Num(order) + ")");
      } else if (order > kMaxJobShOrder) {
        errors_.Add(p + ".shOrder",
                    Num(order) + " is above the highest supported order, " + Num(kMaxJobShOrder));
      } else if (Above(order, limits_.maxShOrder)) {
        errors_.Add(p + ".shOrder",
                    Num(order) + " is above the limit of " + Num(limits_.maxShOrder));
      }
    }
    if (!v1::BakeSettings::Quality_IsValid(s.quality())) {
      errors_.Add(p + ".quality", "unknown value " + Num(int(s.quality())));
    }
    const QualityPreset preset = PresetFor(s.quality());
    const std::string presetPath =
        p + ".quality (" + v1::BakeSettings::Quality_Name(s.quality()) + ")";
    // Numbers left out come from the preset, or with none from the defaults (PresetFor): the
    // limits hold for them as for given ones.
    const bool hasPreset = s.quality() != v1::BakeSettings::QUALITY_UNSPECIFIED;
    if (s.has_samples_per_probe()) {
      SamplesLimit(s.samples_per_probe(), p + ".samplesPerProbe");
    } else {
      SamplesLimit(preset.samplesPerProbe,
                   hasPreset ? presetPath : p + ".samplesPerProbe (default)");
    }
    if (s.has_max_depth()) {
      DepthLimit(s.max_depth(), p + ".maxDepth");
    } else {
      DepthLimit(preset.maxDepth, hasPreset ? presetPath : p + ".maxDepth (default)");
    }
    if (s.has_target_rel_error() && std::isfinite(s.target_rel_error()) &&
        !(s.target_rel_error() >= 0 && s.target_rel_error() < 1)) {
      errors_.Add(p + ".targetRelError",
                  "must be in [0, 1) (got " + Num(s.target_rel_error()) + ")");
    }
    if (!v1::BakeSettings::Window_IsValid(s.window())) {
      errors_.Add(p + ".window", "unknown value " + Num(int(s.window())));
    } else if (s.window() != v1::BakeSettings::WINDOW_UNSPECIFIED &&
               s.window() != v1::BakeSettings::NONE && !s.irradiance()) {
      errors_.Add(p + ".window", v1::BakeSettings::Window_Name(s.window()) +
                                     " applies to the irradiance grids: set irradiance to true, "
                                     "or window to NONE");
    }
    if (s.has_window_width() && std::isfinite(s.window_width()) && !(s.window_width() > 0)) {
      errors_.Add(p + ".windowWidth", "must be > 0 (got " + Num(s.window_width()) + ")");
    }
    if (!v1::BakeSettings::Estimator_IsValid(s.estimator()))
      errors_.Add(p + ".estimator", "unknown value " + Num(int(s.estimator())));
    if (!v1::BakeSettings::Sampler_IsValid(s.sampler()))
      errors_.Add(p + ".sampler", "unknown value " + Num(int(s.sampler())));
    if (s.has_rr_min_depth() && s.rr_min_depth() < 1)
      errors_.Add(p + ".rrMinDepth", "must be >= 1 (got " + Num(s.rr_min_depth()) + ")");
    if (s.has_batches() && !(s.batches() >= 2 && s.batches() <= 1024))
      errors_.Add(p + ".batches", "must be in [2, 1024] (got " + Num(s.batches()) + ")");
    if (s.has_backface_fraction() && std::isfinite(s.backface_fraction()) &&
        !(s.backface_fraction() > 0 && s.backface_fraction() <= 1)) {
      errors_.Add(p + ".backfaceFraction",
                  "must be in (0, 1] (got " + Num(s.backface_fraction()) + ")");
    }
    if (s.has_relocation_max_offset() && std::isfinite(s.relocation_max_offset()) &&
        !(s.relocation_max_offset() >= 0 && s.relocation_max_offset() <= 0.5)) {
      errors_.Add(p + ".relocationMaxOffset",
                  "must be in [0, 0.5] (a fraction of the smallest grid spacing; got " +
                      Num(s.relocation_max_offset()) + ")");
    }
    if (s.has_sky_transfer()) {
      const int order = s.sky_transfer().order();
      const std::string path = p + ".skyTransfer.order";
      if (order < 0 || order > kMaxJobShOrder) {
        errors_.Add(path, "must be in [0, " + Num(kMaxJobShOrder) +
                              "] (the sky's SH order; 0 turns sky transfer off; got " + Num(order) +
                              ")");
      } else if (Above(order, limits_.maxShOrder)) {
        errors_.Add(path, Num(order) + " is above the limit of " + Num(limits_.maxShOrder));
      } else if (order > 0 &&
                 (s.has_target_rel_error() ? s.target_rel_error() : preset.targetRelError) > 0) {
        // std_error measures the radiance grids (the local lights), not T: adaptive sampling
        // would stop on the local lights' noise alone.
        errors_.Add(path, std::string("sky transfer does not support adaptive sampling "
                                      "(targetRelError > 0") +
                              (s.has_target_rel_error() ? "" : ", from the quality preset") +
                              "): std_error measures the local lights only; set "
                              "targetRelError to 0");
      }
    }
  }

  void SamplesLimit(int64_t samples, const std::string& path) {
    if (samples < 1) {
      errors_.Add(path, "must be >= 1 (got " + Num(samples) + ")");
    } else if (Above(double(samples), double(limits_.maxSamplesPerProbe))) {
      errors_.Add(path, Num(samples) + " samples per probe, above the limit of " +
                            Num(limits_.maxSamplesPerProbe));
    }
  }

  void DepthLimit(int depth, const std::string& path) {
    if (depth < 1) {
      errors_.Add(path, "must be >= 1 (got " + Num(depth) + ")");
    } else if (Above(depth, limits_.maxDepth)) {
      errors_.Add(path,
                  "maxDepth " + Num(depth) + " is above the limit of " + Num(limits_.maxDepth));
    }
  }

  const JobLimits& limits_;
  ErrorList errors_;
};

}  // namespace

absl::Status ValidateJobSpec(const v1::JobSpec& job, const JobLimits& limits) {
  return Validator(limits).Run(job);
}

}  // namespace probebake
