// The scene a bake sees: validated, in world space, in double precision, with every asset loaded.
// Built from a JobSpec by BuildBakeJob (probebake/job/job.h); the tracer never sees protobuf.
//
// Conventions (docs/job-format.md): lengths in scene units; RGB is linear Rec.709; radiance per
// steradian per unit area; directions are unit vectors. A triangle's front face is
// counter-clockwise, geometric normal (b - a) x (c - a). Geometry occludes from both sides.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "probebake/math/mat3.h"
#include "probebake/math/vec3.h"

namespace probebake {

// An 8-bit image a material samples: texel (x, y) at rgba[4 (x + width y)], row 0 the image's
// top, the file's values (colour channels as encoded, alpha linear).
struct Texture {
  std::string name;  // the path the model wrote, for messages
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;
  bool hasAlpha = false;  // the file has an alpha channel (else every alpha is 255)
};

enum class TextureWrap : uint8_t { kRepeat, kClamp, kMirror };

// A texture as a material reads it (texture_sample.h): at the mesh's per-vertex image coordinates
// for this map (x right, y down, [0, 1]^2 spanning the image once, any uv transform of the file
// already applied), bilinear between texel centres after decoding sRGB colour channels when
// `srgb`.
struct TextureMap {
  std::shared_ptr<const Texture> image;  // null: no map
  TextureWrap wrapX = TextureWrap::kRepeat, wrapY = TextureWrap::kRepeat;
  bool srgb = true;
};

// A diffuse material. A mesh file's own materials may vary over the surface: textures and vertex
// colours multiply the constant factors (docs/job-format.md, "The file's own materials").
struct Material {
  std::string name;
  Vec3d albedo;               // each channel in [0, 1)
  Vec3d emission;             // radiance, each channel >= 0
  TextureMap albedoMap;       // multiplies albedo; its alpha multiplies coverage
  TextureMap emissionMap;     // multiplies emission
  TextureMap coverageMap;     // multiplies coverage: its alpha, or red without alpha (never sRGB)
  bool vertexColors = false;  // the mesh's colors multiply albedo (RGB) and coverage (A)
  double coverage = 1;        // the alpha factor, [0, 1]
  // Cutout: hits where the coverage is below this pass through, for every ray (0: opaque).
  double alphaCutoff = 0;
  // Both sides are front faces: for emission and for probe validity (both sides always reflect).
  bool doubleSided = false;

  // Whether albedo or coverage vary over the surface (textures, vertex colours).
  bool AlbedoVaries() const { return albedoMap.image || vertexColors; }
  bool HasCutout() const { return alphaCutoff > 0; }
};

// Where an instanced mesh is placed: a world point is linear * p + translation for p in the
// mesh's own frame. linear is invertible (its determinant not zero). A mirroring placement
// (negative determinant) keeps the mesh's front faces: front normals are inverse(linear)^T times
// the mesh's own, as a glTF node that mirrors its mesh keeps them.
struct MeshPlacement {
  Mat3d linear;
  Vec3d translation;

  Vec3d Apply(const Vec3d& p) const { return linear * p + translation; }
};

// Triangles in world space (the job's transform already applied), or, when `placements` is not
// empty, in the mesh's own frame and placed once per entry: a mesh a model places under several
// nodes is stored (and held by Embree) once. An instanced mesh never emits: the job builder places
// an emissive mesh's copies in world space instead, since a light is sampled per triangle.
struct TriangleMesh {
  std::string name;
  std::vector<MeshPlacement> placements;
  std::vector<Vec3d> positions;
  std::vector<uint32_t> indices;  // 3 per triangle, all < positions.size()
  uint32_t material = 0;          // index into Scene::materials
  // Per vertex, present when the material has the map: its image coordinates (TextureMap).
  std::vector<std::array<float, 2>> albedoUv, emissionUv, coverageUv;
  // Per vertex, present when the material has vertex colours: linear RGBA.
  std::vector<std::array<float, 4>> colors;

  size_t TriangleCount() const { return indices.size() / 3; }
  // The triangles the scene holds through this mesh: TriangleCount() times its placements.
  size_t PlacedTriangleCount() const {
    return TriangleCount() * (placements.empty() ? 1 : placements.size());
  }
};

// [*lo, *hi] grown by the corners of the box [a, b] under `placement` (a box around the placed
// box, not always the tightest).
inline void GrowPlacedBox(const MeshPlacement& placement, const Vec3d& a, const Vec3d& b, Vec3d* lo,
                          Vec3d* hi) {
  for (int k = 0; k < 8; ++k) {
    const Vec3d x = placement.Apply({k & 1 ? b.x : a.x, k & 2 ? b.y : a.y, k & 4 ? b.z : a.z});
    *lo = Min(*lo, x);
    *hi = Max(*hi, x);
  }
}

// World bounds of `mesh` grown into [*lo, *hi]: its positions, or, when instanced, their box
// under every placement (GrowPlacedBox).
inline void GrowMeshBounds(const TriangleMesh& mesh, Vec3d* lo, Vec3d* hi) {
  if (mesh.placements.empty()) {
    for (const Vec3d& p : mesh.positions) *lo = Min(*lo, p), *hi = Max(*hi, p);
    return;
  }
  if (mesh.positions.empty()) return;
  Vec3d a = mesh.positions[0], b = mesh.positions[0];
  for (const Vec3d& p : mesh.positions) a = Min(a, p), b = Max(b, p);
  for (const MeshPlacement& placement : mesh.placements) GrowPlacedBox(placement, a, b, lo, hi);
}

struct PointLight {
  Vec3d position;
  Vec3d intensity;  // radiant intensity, W/sr per channel
};

struct SpotLight {
  Vec3d position;
  Vec3d direction;      // unit, the direction light travels along the axis
  Vec3d intensity;      // on the axis
  double cosInner = 1;  // cos of the inner half-angle: full intensity inside
  double cosOuter = 0;  // cos of the outer half-angle: zero outside; cosOuter <= cosInner
};

struct DirectionalLight {
  Vec3d direction;          // unit, the direction light travels (into the scene)
  Vec3d irradiance;         // on a surface facing the light
  double cosHalfAngle = 1;  // cos of the source's angular radius; 1 = delta light
};

// Parallelogram corner + s edge1 + t edge2, s, t in [0, 1].
struct RectLight {
  Vec3d corner, edge1, edge2;
  Vec3d radiance;
  bool twoSided = false;  // else emits on the side of edge1 x edge2
};

struct DiskLight {
  Vec3d center;
  Vec3d normal;  // unit, the emitting side
  double radius = 0;
  Vec3d radiance;
  bool twoSided = false;
};

struct SphereLight {
  Vec3d center;
  double radius = 0;
  Vec3d radiance;
};

using Light =
    std::variant<PointLight, SpotLight, DirectionalLight, RectLight, DiskLight, SphereLight>;

// A lat-long HDR image, 32-bit float RGB, as stored in the file (row 0 is the image's top).
// Pixel <-> map direction follows Imf::LatLongMap over the data window; `worldFromMap` turns map
// directions into world directions (the job's `up` and `rotationDeg`), `scale` multiplies radiance.
struct EnvironmentMap {
  int width = 0, height = 0;
  int dataWindowMinX = 0, dataWindowMinY = 0;  // OpenEXR data window origin
  std::vector<float> rgb;                      // width * height * 3, row-major
  double scale = 1;
  Mat3d worldFromMap;  // a rotation
  std::string digest;  // sha256 of the file's bytes, for logs and caches
};

struct Environment {
  enum class Kind { kNone, kUniform, kMap };
  Kind kind = Kind::kNone;
  Vec3d radiance;                             // kUniform
  std::shared_ptr<const EnvironmentMap> map;  // kMap
};

// Homogeneous medium filling `bounds`; vacuum outside.
struct Medium {
  Vec3d sigmaA, sigmaS;  // per scene unit
  double g = 0;          // Henyey-Greenstein mean cosine, (-1, 1)
  Vec3d boundsMin, boundsMax;
};

// The most a scene's finite parts (meshes, area, point and spot lights) may span on an axis, in
// scene units. The tracer holds geometry in single precision about the scene's centre, and
// Embree's triangle test multiplies three coordinates, which overflows float past ~1e13 from the
// centre: a tilted emissive square 2e13 wide vanished, at 6e12 it baked right (tested at the
// limit by bake test Extremes.ATiltedSquareAtTheSceneSpanLimitBakesRight).
inline constexpr double kMaxSceneSpan = 2e12;

struct Scene {
  std::vector<Material> materials;
  std::vector<TriangleMesh> meshes;
  std::vector<Light> lights;
  Environment environment;
  std::optional<Medium> medium;
};

enum class Placement { kAll, kOutsideGeometry, kNearSurfaces };

// Probe (i, j, k) sits at origin + spacing * (i, j, k); linear index i + nx (j + ny k).
struct ProbeGrid {
  Vec3d origin;   // the grid's min corner
  Vec3d spacing;  // > 0 per axis
  int counts[3] = {1, 1, 1};
  Placement placement = Placement::kOutsideGeometry;
  double surfaceDistance = 0;  // kNearSurfaces only

  int64_t ProbeCount() const { return int64_t(counts[0]) * counts[1] * counts[2]; }
  int64_t LinearIndex(int i, int j, int k) const {
    return i + int64_t(counts[0]) * (j + int64_t(counts[1]) * k);
  }
  void Coords(int64_t index, int* i, int* j, int* k) const {
    *i = int(index % counts[0]);
    *j = int((index / counts[0]) % counts[1]);
    *k = int(index / (int64_t(counts[0]) * counts[1]));
  }
  Vec3d Position(int i, int j, int k) const {
    return {origin.x + spacing.x * i, origin.y + spacing.y * j, origin.z + spacing.z * k};
  }
};

enum class ShWindow { kNone, kHanning, kLanczos, kAuto };
enum class Estimator { kNeeMis, kLightSampling, kDirectionSampling };
enum class SamplerKind { kSobol, kIndependent };

// Settings with every default and preset resolved.
struct BakeSettings {
  int shOrder = 2;
  int64_t samplesPerProbe = 1024;
  int maxDepth = 8;
  double targetRelError = 0;
  uint64_t seed = 1;
  bool irradiance = false;
  ShWindow window = ShWindow::kNone;
  double windowWidth = 3;
  Estimator estimator = Estimator::kNeeMis;
  SamplerKind sampler = SamplerKind::kSobol;
  bool russianRoulette = true;
  int rrMinDepth = 3;
  int batches = 4;
  double backfaceFraction = 0.5;
  // Fraction of the smallest grid spacing a probe may be moved by (0: no relocation).
  double relocationMaxOffset = 0;
  bool visibility = false;  // gather visibility moments
  // Ls of the sky transfer (BakeSettings.sky_transfer.order in job.proto); 0: off, the
  // environment bakes into the radiance like any light.
  int skyTransferOrder = 0;
  // Light traced from directional lights and joined to the probes, weighed against the probes'
  // own paths (core/src/bake/distant_light_paths.h). Not a job field: off only to measure it.
  bool distantLightTracing = true;
  // The environment's next-event samples drawn partly from a guide of where it reaches each
  // region (core/src/bake/environment_guide.h). Not a job field: off only to measure it.
  bool environmentGuide = true;
  // When > 0, the least factor of the light-visibility table (core/src/bake/light_visibility.h)
  // instead of its own. Not a job field: set (to 1/8) only to measure the default before baker
  // version 21.
  double lightVisibilityFloor = 0;
  // Russian roulette on the paths' weak shadow rays (core/src/bake/shadow_roulette.h). Not a job
  // field: off only to measure it.
  bool shadowRoulette = true;
};

// A job ready to bake.
struct BakeJob {
  Scene scene;
  ProbeGrid grid;
  BakeSettings settings;
  std::string sceneDigest;   // sha256 hex of the canonical scene (assets by content digest)
  std::string jobDigest;     // sha256 hex of the canonical job + kBakerVersion (the cache key)
  std::string settingsJson;  // the resolved settings as JSON, recorded in the volume
  // What the job's files hold that the bake ignores ("scene.meshes[0]: KHR_materials_sheen"),
  // in mesh order, recorded in the volume's `ignored` metadata.
  std::vector<std::string> ignored;
};

}  // namespace probebake
