// Mesh import through BuildBakeJob: OBJ, PLY (ascii and binary), glTF with an embedded buffer and
// GLB, node and job transforms, double precision far from the origin, zero-area triangles, limits.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>
#include <tuple>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "job/test_util.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"

namespace probebake {
namespace {

using testing::HasFieldError;
using testing::TempDir;

constexpr char kIdentity[] = "[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]";

// A job with one mesh read from `file` (in `dir`) and the given transform.
absl::StatusOr<BakeJob> BuildMeshJob(const TempDir& dir, const std::string& file,
                                     const std::string& transform = kIdentity,
                                     const JobLimits& limits = {}) {
  const std::string json =
      R"({"scene": {"materials": [{"name": "m"}], "meshes": [{"file": ")" + file +
      R"(", "material": "m", "transform": )" + transform +
      R"(}]}, "grid": {"min": [0, 0, 0], "max": [0, 0, 0], "counts": [1, 1, 1]}})";
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  EXPECT_TRUE(job.ok()) << job.status();
  if (!job.ok()) return job.status();
  return BuildBakeJob(*job, LocalAssetSource(dir.path()), limits);
}

using Point = std::tuple<double, double, double>;

// The distinct vertex positions the triangles of `mesh` use.
std::set<Point> UsedPositions(const TriangleMesh& mesh) {
  std::set<Point> out;
  for (uint32_t i : mesh.indices)
    out.insert({mesh.positions[i].x, mesh.positions[i].y, mesh.positions[i].z});
  return out;
}

Vec3d Normal(const TriangleMesh& mesh, size_t t) {
  const Vec3d a = mesh.positions[mesh.indices[3 * t]];
  return Cross(mesh.positions[mesh.indices[3 * t + 1]] - a,
               mesh.positions[mesh.indices[3 * t + 2]] - a);
}

double Area(const TriangleMesh& mesh) {
  double area = 0;
  for (size_t t = 0; t < mesh.TriangleCount(); ++t) area += Length(Normal(mesh, t)) / 2;
  return area;
}

// A quad (0,0,0) (2,0,0) (2,1,0) (0,1,0) facing +z and a triangle (0,0,1) (-1.25,0,1) (0,0.5,1)
// facing -z ((-1.25, 0, 0) x (0, 0.5, 0) = (0, 0, -0.625)), in two objects, with a line element and
// an unresolvable mtllib.
constexpr char kObj[] = R"(mtllib missing.mtl
o quad
v 0 0 0
v 2 0 0
v 2 1 0
v 0 1 0
usemtl red
f 1 2 3 4
o tri
v 0 0 1
v 0 0.5 1
v -1.25 0 1
f 5 7 6
l 1 5
)";

TEST(MeshImport, ObjWithTransform) {
  TempDir dir;
  dir.Write("scene.obj", kObj);
  // p' = (2x + 10, y + 20, -z + 30): a mirror, so the winding flips too.
  const absl::StatusOr<BakeJob> built =
      BuildMeshJob(dir, "scene.obj", "[2,0,0,10, 0,1,0,20, 0,0,-1,30, 0,0,0,1]");
  ASSERT_TRUE(built.ok()) << built.status();
  ASSERT_EQ(built->scene.meshes.size(), 1u);
  const TriangleMesh& mesh = built->scene.meshes[0];
  EXPECT_EQ(mesh.TriangleCount(), 3u);
  const std::set<Point> expected = {{10, 20, 30}, {14, 20, 30},   {14, 21, 30}, {10, 21, 30},
                                    {10, 20, 29}, {10, 20.5, 29}, {7.5, 20, 29}};
  EXPECT_EQ(UsedPositions(mesh), expected);
  // Areas scale by |det| = 2: quad 2 -> 4, triangle 0.3125 -> 0.625.
  EXPECT_EQ(Area(mesh), 4.625);
  // Winding is kept: the geometric normal (b - a) x (c - a) transforms with the cofactor matrix
  // det(M) M^-T = diag(-1, -2, 2), so the quad (file normal +z, now at z = 30) still faces +z and
  // the triangle (file normal -z, now at z = 29) still faces -z.
  for (size_t t = 0; t < mesh.TriangleCount(); ++t) {
    const Vec3d n = Normal(mesh, t);
    const double z = mesh.positions[mesh.indices[3 * t]].z;
    EXPECT_EQ(n.z > 0, z == 30) << "triangle " << t << " normal " << n;
  }
}

std::string PlyHeader(const char* format) {
  return std::string("ply\nformat ") + format +
         " 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
         "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
}

// Vertices of the PLY tests and their faces: a quad and a triangle.
constexpr float kPlyVertices[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5f, 0.5f, 2}};

void ExpectPlyMesh(const absl::StatusOr<BakeJob>& built) {
  ASSERT_TRUE(built.ok()) << built.status();
  const TriangleMesh& mesh = built->scene.meshes[0];
  EXPECT_EQ(mesh.TriangleCount(), 3u);
  // Job transform: translate by (0, 0, 5).
  std::set<Point> expected;
  for (const auto& v : kPlyVertices) expected.insert({v[0], v[1], double(v[2]) + 5});
  EXPECT_EQ(UsedPositions(mesh), expected);
  EXPECT_EQ(Area(mesh), 1 + Length(Cross(Vec3d(1, 0, 0) - Vec3d(0.5, 0.5, 2),
                                         Vec3d(1, 1, 0) - Vec3d(0.5, 0.5, 2))) /
                                2);
}

// The PLY tests' mesh as an ASCII file with line ends `eol`, and as a little-endian binary one.
std::string PlyAsciiFile(const std::string& eol = "\n") {
  std::string ply = PlyHeader("ascii");
  for (size_t at = ply.find('\n'); eol != "\n" && at != std::string::npos;
       at = ply.find('\n', at + eol.size()))
    ply.replace(at, 1, eol);
  for (const auto& v : kPlyVertices)
    ply += std::to_string(v[0]) + " " + std::to_string(v[1]) + " " + std::to_string(v[2]) + eol;
  return ply + "4 0 1 2 3" + eol + "3 4 1 2" + eol;
}

std::string PlyBinaryFile() {
  std::string ply = PlyHeader("binary_little_endian");
  auto put = [&ply](const void* p, size_t n) { ply.append(static_cast<const char*>(p), n); };
  for (const auto& v : kPlyVertices) put(v, sizeof v);
  const unsigned char four = 4, three = 3;
  const int32_t quad[4] = {0, 1, 2, 3}, tri[3] = {4, 1, 2};
  put(&four, 1);
  put(quad, sizeof quad);
  put(&three, 1);
  put(tri, sizeof tri);
  return ply;
}

constexpr char kUp5[] = "[1,0,0,0, 0,1,0,0, 0,0,1,5, 0,0,0,1]";

TEST(MeshImport, PlyAscii) {
  TempDir dir;
  dir.Write("m.ply", PlyAsciiFile());
  ExpectPlyMesh(BuildMeshJob(dir, "m.ply", kUp5));
}

TEST(MeshImport, PlyBinaryLittleEndian) {
  TempDir dir;
  dir.Write("m.ply", PlyBinaryFile());
  ExpectPlyMesh(BuildMeshJob(dir, "m.ply", kUp5));
}

// glTF 2.0 pieces: one mesh (a right triangle (0,0,0) (1,0,0) (0,1,0), uint16 indices) placed by
// two nodes: node 0 translates by (100, 0, 0) and has child node 1 scaling by 2 with the mesh;
// node 2 holds the mesh untransformed.
std::string GltfBuffer() {
  const float positions[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const uint16_t indices[4] = {0, 1, 2, 0};  // padded to 4-byte length
  std::string bin(reinterpret_cast<const char*>(positions), sizeof positions);
  bin.append(reinterpret_cast<const char*>(indices), sizeof indices);
  return bin;
}

std::string GltfJson(const std::string& bufferUri, size_t bufferLength) {
  const std::string uri = bufferUri.empty() ? "" : R"("uri": ")" + bufferUri + R"(", )";
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 2]}],
    "nodes": [{"translation": [100, 0, 0], "children": [1]}, {"mesh": 0, "scale": [2, 2, 2]},
              {"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
    "buffers": [{)" +
         uri + R"("byteLength": )" + std::to_string(bufferLength) + R"(}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                    {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                   "min": [0, 0, 0], "max": [1, 1, 0]},
                  {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]})";
}

void ExpectGltfMesh(const absl::StatusOr<BakeJob>& built) {
  ASSERT_TRUE(built.ok()) << built.status();
  const TriangleMesh& mesh = built->scene.meshes[0];
  ASSERT_EQ(mesh.TriangleCount(), 2u);  // one mesh, two instances
  // Node transforms, then the job's quarter turn about z: (x, y, z) -> (-y, x, z).
  const std::set<Point> expected = {{0, 100, 0}, {0, 102, 0}, {-2, 100, 0},  // T(100) S(2)
                                    {0, 0, 0},   {0, 1, 0},   {-1, 0, 0}};   // untransformed
  EXPECT_EQ(UsedPositions(mesh), expected);
  for (size_t t = 0; t < 2; ++t) EXPECT_GT(Normal(mesh, t).z, 0) << t;  // winding kept
}

constexpr char kQuarterTurn[] = "[0,-1,0,0, 1,0,0,0, 0,0,1,0, 0,0,0,1]";

TEST(MeshImport, GltfWithEmbeddedBuffer) {
  TempDir dir;
  const std::string bin = GltfBuffer();
  dir.Write("m.gltf", GltfJson("data:application/octet-stream;base64," + absl::Base64Escape(bin),
                               bin.size()));
  ExpectGltfMesh(BuildMeshJob(dir, "m.gltf", kQuarterTurn));
}

TEST(MeshImport, Glb) {
  TempDir dir;
  const std::string bin = GltfBuffer();
  std::string json = GltfJson("", bin.size());
  while (json.size() % 4) json += ' ';
  std::string glb;
  auto u32 = [&glb](uint32_t x) { glb.append(reinterpret_cast<const char*>(&x), 4); };
  u32(0x46546C67);  // "glTF"
  u32(2);
  u32(uint32_t(12 + 8 + json.size() + 8 + bin.size()));
  u32(uint32_t(json.size()));
  u32(0x4E4F534A);  // "JSON"
  glb += json;
  u32(uint32_t(bin.size()));
  u32(0x004E4942);  // "BIN\0"
  glb += bin;
  dir.Write("m.glb", glb);
  ExpectGltfMesh(BuildMeshJob(dir, "m.glb", kQuarterTurn));
}

TEST(MeshImport, FormatOverridesTheExtension) {
  TempDir dir;
  dir.Write("scene.txt", kObj);
  const std::string json = R"({"scene": {"materials": [{"name": "m"}], "meshes": [{"file":
      "scene.txt", "format": "OBJ", "material": "m"}]}, "grid": {"min": [0, 0, 0],
      "max": [0, 0, 0], "counts": [1, 1, 1]}})";
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  ASSERT_TRUE(job.ok()) << job.status();
  const absl::StatusOr<BakeJob> built = BuildBakeJob(*job, LocalAssetSource(dir.path()), {});
  ASSERT_TRUE(built.ok()) << built.status();
  EXPECT_EQ(built->scene.meshes[0].TriangleCount(), 3u);
}

TEST(MeshImport, BadFilesAreRejectedWithThePath) {
  TempDir dir;
  dir.Write("garbage.ply", "this is not a ply file");
  EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "garbage.ply").status(), "scene.meshes[0].file",
                            "cannot import \"garbage.ply\" as ply"));
  dir.Write("empty.obj", "");
  EXPECT_TRUE(
      HasFieldError(BuildMeshJob(dir, "empty.obj").status(), "scene.meshes[0].file", "empty"));
  dir.Write("lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\n");
  EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "lines.obj").status(), "scene.meshes[0].file",
                            "\"lines.obj\""));
  // Control characters in a missing file's name are escaped in both its spellings.
  const absl::Status bell = BuildMeshJob(dir, "no\\u0007pe.obj").status();
  EXPECT_TRUE(HasFieldError(bell, "scene.meshes[0].file", "cannot read \"no\\x07pe.obj\" ("));
  EXPECT_NE(bell.message().find("no\\x07pe.obj)"), std::string::npos) << bell;
  EXPECT_EQ(bell.message().find('\a'), std::string::npos) << bell;
  dir.Write("external.gltf", GltfJson("external.bin", GltfBuffer().size()));
  EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "external.gltf").status(), "scene.meshes[0].file",
                            "\"external.gltf\" references \"external.bin\": cannot read it"));
}

TEST(MeshImport, ExternalBuffersAreReadBesideTheModelAndNothingOutsideTheJobFolder) {
  TempDir dir;
  const std::string bin = GltfBuffer();
  std::filesystem::create_directories(std::filesystem::path(dir.File("sub")));
  dir.Write("sub/buffer.bin", bin);
  // A relative uri is read relative to the model, and its bytes are in the job digest.
  dir.Write("sub/m.gltf", GltfJson("./buffer.bin", bin.size()));
  const absl::StatusOr<BakeJob> built = BuildMeshJob(dir, "sub/m.gltf", kQuarterTurn);
  ExpectGltfMesh(built);
  dir.Write("sub/buffer.bin", bin.substr(0, bin.size() - 2) + std::string(2, '\x7f'));
  const absl::StatusOr<BakeJob> changed = BuildMeshJob(dir, "sub/m.gltf", kQuarterTurn);
  ASSERT_TRUE(changed.ok()) << changed.status();
  EXPECT_NE(built->jobDigest, changed->jobDigest);

  // Absolute paths, schemes, paths leading out of the job folder and symlinks out of it are
  // refused, naming the mesh's field and the path the model wrote.
  TempDir outside;
  outside.Write("buffer.bin", bin);
  const std::vector<std::pair<std::string, std::string>> refused = {
      {outside.File("buffer.bin"), "an absolute path"},
      {"file:///etc/passwd", "a URI scheme"},
      {"http://example.com/b.bin", "a URI scheme"},
      {"../../b.bin", "it leads out of the job file's folder"},
      {"../link.bin", "a symlink leads out of the job file's folder"},
      {"missing.bin", "cannot read it"}};
  std::filesystem::create_symlink(outside.File("buffer.bin"), dir.File("link.bin"));
  for (const auto& [uri, reason] : refused) {
    dir.Write("sub/bad.gltf", GltfJson(uri, bin.size()));
    EXPECT_TRUE(
        HasFieldError(BuildMeshJob(dir, "sub/bad.gltf").status(), "scene.meshes[0].file",
                      "\"sub/bad.gltf\" references \"" + NormalizeModelPath(uri) + "\": " + reason))
        << uri;
  }
}

TEST(MeshImport, OnlyTheNamedFormatIsTried) {
  // Assimp tries every importer it has by signature when no importer of the named extension
  // accepts the bytes: an ASCII STL sent as glTF was read as STL.
  TempDir dir;
  const std::string stl =
      "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
      "endloop\nendfacet\nendsolid t\n";
  dir.Write("m.gltf", stl);
  dir.Write("m.glb", stl);
  EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "m.gltf").status(), "scene.meshes[0].file",
                            "cannot import \"m.gltf\" as gltf: it is not a gltf file"));
  EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "m.glb").status(), "scene.meshes[0].file",
                            "cannot import \"m.glb\" as glb: it does not start with a GLB header"));
}

TEST(MeshImport, PlyHeadersAreCheckedBeforeAssimpReadsThem) {
  // Assimp's PLY reader crashed on a NUL byte in the header and looped forever without an
  // end_header line.
  TempDir dir;
  const std::string header = PlyHeader("binary_little_endian");
  ASSERT_EQ(header.substr(header.size() - 11), "end_header\n");
  const std::string withNul = header.substr(0, header.size() - 11) + std::string(1, '\0') +
                              header.substr(header.size() - 11) + std::string(64, '\0');
  const struct {
    std::string bytes;
    std::string message;
  } cases[] = {
      {withNul, "its header has a byte that is not text (0) on line"},
      {"ply\nformat ascii 1.0\n", "its header has no end_header line"},
      {"ply\nformat ascii 1.0\nelement vertex 4\npr", "its header has no end_header line"},
      {"ply\n", "its header has no end_header line"},
      {"ply\nformat ascii 2.0\nend_header\n", "line 2 names an unknown format"},
      {"ply\nelement vertex 0\nend_header\n", "its header has no format line"},
      {"solid t\n", "it does not start with a \"ply\" line"},
  };
  for (const auto& c : cases) {
    dir.Write("m.ply", c.bytes);
    EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "m.ply").status(), "scene.meshes[0].file",
                              "cannot import \"m.ply\" as ply: " + c.message))
        << c.message;
  }
  // CRLF line ends are fine.
  dir.Write("crlf.ply", PlyAsciiFile("\r\n"));
  ExpectPlyMesh(BuildMeshJob(dir, "crlf.ply", kUp5));
}

TEST(MeshImport, PlyBodiesMustHoldWhatTheHeaderDeclares) {
  // Fuzzed files whose declared sizes assimp trusted: it ran for ever, or asserted and aborted.
  TempDir dir;
  const std::string binary = PlyBinaryFile();
  auto replaced = [](std::string text, const std::string& from, const std::string& to) {
    text.replace(text.find(from), from.size(), to);
    return text;
  };
  const std::string ascii = PlyAsciiFile();
  std::string garbageCount = binary;
  garbageCount[PlyHeader("binary_little_endian").size() + sizeof kPlyVertices] = char(200);
  const struct {
    std::string bytes;
    std::string message;
  } cases[] = {
      {replaced(binary, "element vertex 5", "element vertex 99999999999"),
       "the body ends before element 'vertex' item"},
      {replaced(ascii, "element face 2", "element face 99999999999"),
       "the body ends before element 'face' item"},
      {garbageCount, "the body ends inside element 'face' item 0"},
      {replaced(binary, "property list uchar int", "property list int int"),
       "the body ends inside element 'face' item"},
      {replaced(ascii, "4 0 1 2 3", "-4 0 1 2 3"),
       "element 'face' item 0 has a list count that is not a non-negative integer"},
      {replaced(binary, "element face 2\nproperty list uchar int vertex_indices\n",
                "element face 2\n"),
       "element 'face' has items but no properties"},
      {replaced(binary, "property float z", "property float32x z"),
       "its header has a property of unknown type on line 6"},
      {replaced(binary, "list uchar int", "list float int"),
       "its header has a list property of unknown or non-integer count type on line 8"},
      {binary.substr(0, binary.size() - 1), "the body ends inside element 'face' item 1"},
  };
  for (const auto& c : cases) {
    dir.Write("m.ply", c.bytes);
    EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "m.ply").status(), "scene.meshes[0].file",
                              "cannot import \"m.ply\" as ply: " + c.message))
        << c.message;
  }
  // Sound structure that assimp's triangulation asserted on: a face with no vertex.
  dir.Write("m.ply", replaced(ascii, "4 0 1 2 3", "0"));
  EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "m.ply").status(), "scene.meshes[0].file",
                            "\"m.ply\" has a face without vertices"));
  // The complete files, and tabs between header words, are fine.
  dir.Write("m.ply", replaced(binary, "element vertex 5", "element\tvertex\t5"));
  ExpectPlyMesh(BuildMeshJob(dir, "m.ply", kUp5));
  dir.Write("m.ply", ascii);
  ExpectPlyMesh(BuildMeshJob(dir, "m.ply", kUp5));
}

TEST(MeshImport, GlbChunksMustFitInTheFile) {
  // A GLB whose JSON chunk declared 4 GiB had assimp allocate and clear 4 GiB.
  TempDir dir;
  std::string json = GltfJson("", GltfBuffer().size());
  while (json.size() % 4) json += ' ';
  std::string glb;
  auto u32 = [&glb](uint32_t x) { glb.append(reinterpret_cast<const char*>(&x), 4); };
  u32(0x46546C67);  // "glTF"
  u32(2);
  u32(uint32_t(12 + 8 + json.size()));
  u32(0xFFFFFFFFu);
  u32(0x4E4F534A);  // "JSON"
  glb += json;
  dir.Write("m.glb", glb);
  EXPECT_TRUE(
      HasFieldError(BuildMeshJob(dir, "m.glb").status(), "scene.meshes[0].file",
                    "cannot import \"m.glb\" as glb: GLB chunk 0 declares 4294967295 bytes"));
  glb.replace(8, 4, std::string("\xff\xff\x00\x00", 4));  // total length past the file
  dir.Write("m.glb", glb);
  EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "m.glb").status(), "scene.meshes[0].file",
                            "its GLB header declares 65535 bytes; the file has"));
}

TEST(MeshImport, GltfNodesMustFormShallowTrees) {
  // Shared children doubled the scene at every level (22 levels: 2.7 GB); deep chains and deeply
  // nested JSON overflowed assimp's stack.
  TempDir dir;
  const std::string bin = GltfBuffer();
  const std::string base =
      GltfJson("data:application/octet-stream;base64," + absl::Base64Escape(bin), bin.size());
  auto withNodes = [&](const std::string& nodes) {
    std::string json = base;
    const size_t from = json.find("\"nodes\": [{");
    const size_t to = json.find("\"meshes\"");
    return json.replace(from, to - from, "\"nodes\": " + nodes + ",\n    ");
  };
  std::string chain = "[";
  for (int i = 0; i < 1100; ++i) chain += "{\"children\": [" + std::to_string(i + 1) + "]}, ";
  chain += "{\"mesh\": 0}]";
  std::string deepJson = base;
  deepJson.replace(deepJson.find("\"asset\""), 0,
                   "\"extras\": " + std::string(150, '[') + std::string(150, ']') + ", ");
  const struct {
    std::string json;
    std::string message;
  } cases[] = {
      {withNodes(R"([{"children": [1, 1]}, {"mesh": 0}, {"mesh": 0}])"),
       "node 1 has two parents (glTF nodes form trees)"},
      {withNodes(R"([{"children": [1]}, {"children": [2]}, {"children": [1], "mesh": 0}])"),
       "node 1 has two parents"},
      {withNodes(R"([{"children": [1]}, {"children": [0], "mesh": 0}, {"mesh": 0}])"),
       "its nodes form a cycle"},
      {withNodes(R"([{"children": [7]}, {"mesh": 0}, {"mesh": 0}])"),
       "node 0 names a child that does not exist"},
      {withNodes(chain), "its nodes nest deeper than 1000 levels"},
      {deepJson, "its JSON nests deeper than 100 levels"},
  };
  for (const auto& c : cases) {
    dir.Write("m.gltf", c.json);
    EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "m.gltf").status(), "scene.meshes[0].file",
                              "cannot import \"m.gltf\" as gltf: " + c.message))
        << c.message;
  }
}

TEST(MeshImport, GltfGeometryAssimpWouldMisreadIsRefused) {
  // Each read "fine" by assimp, and baked wrong: int16 positions taken for floats, a dangling index
  // dropped, a mesh morphed in any viewer baked unmorphed (black-box import audit).
  TempDir dir;
  const std::string bin = GltfBuffer();
  const std::string base =
      GltfJson("data:application/octet-stream;base64," + absl::Base64Escape(bin), bin.size());
  // base with each (from, to) of `edits` applied in turn.
  auto edited = [&](std::vector<std::pair<std::string, std::string>> edits) {
    std::string json = base;
    for (const auto& [from, to] : edits) {
      const size_t at = json.find(from);
      EXPECT_NE(at, std::string::npos) << from;
      if (at != std::string::npos) json.replace(at, from.size(), to);
    }
    return json;
  };
  const std::string meshes = R"("meshes": [{)";
  const struct {
    std::string json;
    std::string message;  // "" when accepted
  } cases[] = {
      {edited({{R"("asset")", R"("extensionsUsed": ["KHR_mesh_quantization"], "asset")"}}),
       "it uses the glTF extension KHR_mesh_quantization, which the importer does not read"},
      {edited({{R"("asset")", R"("extensionsRequired": ["EXT_meshopt_compression"], "asset")"}}),
       "it uses the glTF extension EXT_meshopt_compression"},
      {edited({{R"("count": 3, "type": "SCALAR")", R"("count": 2, "type": "SCALAR")"}}),
       "mesh 0 primitive 0 is a triangle list of 2 indices, not a multiple of 3"},
      {edited({{R"(, "indices": 1, "mode": 4)", ""},
               {R"("count": 3, "type": "VEC3")", R"("count": 4, "type": "VEC3")"}}),
       "mesh 0 primitive 0 is a triangle list of 4 vertices, not a multiple of 3"},
      {edited({{meshes, meshes + R"("weights": [0, 0.5], )"}}),
       "node 1 morphs mesh 0 (non-zero morph target weights), which is not applied"},
      // Weights of zero leave the mesh as it is; a node's weights override its mesh's.
      {edited({{meshes, meshes + R"("weights": [0], )"}}), ""},
      {edited({{meshes, meshes + R"("weights": [1], )"},
               {R"({"mesh": 0, "scale": [2, 2, 2]})",
                R"({"mesh": 0, "scale": [2, 2, 2], "weights": [0]})"},
               {R"({"mesh": 0}])", R"({"mesh": 0, "weights": [0]}])"}}),
       ""},
      {edited({{R"({"mesh": 0}])", R"({"mesh": 0, "weights": [0.25]}])"}}), "node 2 morphs mesh 0"},
      {edited({{R"("asset")", R"("extensionsUsed": ["KHR_meshopt_compression"], "asset")"}}),
       "it uses the glTF extension KHR_meshopt_compression"},
      // Only triangle lists are counted: a strip of 4 indices is two triangles.
      {edited({{R"("count": 3, "type": "SCALAR")", R"("count": 4, "type": "SCALAR")"},
               {R"("byteOffset": 36, "byteLength": 6)", R"("byteOffset": 36, "byteLength": 8)"},
               {R"("mode": 4)", R"("mode": 5)"}}),
       ""},
  };
  for (const auto& c : cases) {
    dir.Write("m.gltf", c.json);
    const absl::StatusOr<BakeJob> built = BuildMeshJob(dir, "m.gltf");
    if (c.message.empty()) {
      EXPECT_TRUE(built.ok()) << built.status();
      continue;
    }
    EXPECT_TRUE(HasFieldError(built.status(), "scene.meshes[0].file", c.message)) << c.message;
  }
}

TEST(MeshImport, GltfIndicesPastTheVerticesAreRefused) {
  // Two triangles over four vertices, the second indexing vertex 9: assimp drops that triangle
  // with only a log line, which would bake a model with a hole (OBJ and PLY are refused alike).
  TempDir dir;
  const float positions[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  for (const uint16_t last : {uint16_t(2), uint16_t(9)}) {
    const uint16_t indices[6] = {0, 1, 2, 1, 3, last};
    std::string bin(reinterpret_cast<const char*>(positions), sizeof positions);
    bin.append(reinterpret_cast<const char*>(indices), sizeof indices);
    const std::string json =
        R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
      "nodes": [{"mesh": 0}],
      "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
      "buffers": [{"uri": "data:application/octet-stream;base64,)" +
        absl::Base64Escape(bin) + R"(", "byteLength": 60}],
      "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                      {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
      "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                     "min": [0, 0, 0], "max": [1, 1, 0]},
                    {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]})";
    dir.Write("m.gltf", json);
    const absl::StatusOr<BakeJob> built = BuildMeshJob(dir, "m.gltf");
    if (last == 2) {
      ASSERT_TRUE(built.ok()) << built.status();
      EXPECT_EQ(built->scene.meshes[0].TriangleCount(), 2u);
    } else {
      EXPECT_TRUE(HasFieldError(built.status(), "scene.meshes[0].file",
                                "some triangles index vertices past the end"))
          << built.status();
    }
  }
}

TEST(MeshImport, PlyTriangleStripsAreRefused) {
  // Assimp kept the first triangle of each strip and dropped the rest, silently.
  TempDir dir;
  dir.Write("m.ply",
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            "property float z\nelement tristrips 1\nproperty list int int vertex_indices\n"
            "end_header\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n4 0 1 3 2\n");
  EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "m.ply").status(), "scene.meshes[0].file",
                            "cannot import \"m.ply\" as ply: it stores triangle strips (element "
                            "'tristrips'), which are not supported"));
}

// An OBJ file holding one convex polygon of n vertices on the unit circle.
std::string ObjPolygon(int n) {
  std::string obj;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * 3.141592653589793 * i / n;
    absl::StrAppend(&obj, "v ", std::cos(a), " ", std::sin(a), " 0\n");
  }
  obj += "f";
  for (int i = 1; i <= n; ++i) absl::StrAppend(&obj, " ", i);
  obj += '\n';
  return obj;
}

TEST(MeshImport, PolygonsTooLargeToTriangulateAreRefusedFirst) {
  // Triangulation takes O(n^2): a 32000-vertex face (1 MB) took 18 s. Refused before it starts.
  TempDir dir;
  dir.Write("big.obj", ObjPolygon(8193));  // 8193^2 > 2^26
  EXPECT_TRUE(
      HasFieldError(BuildMeshJob(dir, "big.obj").status(), "scene.meshes[0].file",
                    "\"big.obj\" has polygons too large to triangulate in time: the squares "
                    "of the vertex counts of its faces of over 64 vertices sum to "
                    "67125249, above 67108864 (the largest, face 0 of mesh 0, has 8193 "
                    "vertices)"));
  dir.Write("fine.obj", ObjPolygon(1000));
  const absl::StatusOr<BakeJob> fine = BuildMeshJob(dir, "fine.obj");
  ASSERT_TRUE(fine.ok()) << fine.status();
  EXPECT_EQ(fine->scene.meshes[0].TriangleCount(), 998u);
}

TEST(MeshImport, ObjWithAByteOrderMarkKeepsItsFirstVertex) {
  // Windows tools write one; assimp read the first line as garbage ("vertex index out of range").
  TempDir dir;
  dir.Write("bom.obj", std::string("\xEF\xBB\xBF") + "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const absl::StatusOr<BakeJob> built = BuildMeshJob(dir, "bom.obj");
  ASSERT_TRUE(built.ok()) << built.status();
  EXPECT_EQ(UsedPositions(built->scene.meshes[0]),
            (std::set<Point>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}));
}

TEST(MeshImport, TriangleLimitCountsFilesAndInlineMeshes) {
  TempDir dir;
  dir.Write("scene.obj", kObj);  // 3 triangles
  JobLimits limits;
  limits.maxTriangles = 2;
  EXPECT_TRUE(HasFieldError(BuildMeshJob(dir, "scene.obj", kIdentity, limits).status(),
                            "scene.meshes[0].file", "exceed the limit of 2"));
  limits.maxTriangles = 3;
  EXPECT_TRUE(BuildMeshJob(dir, "scene.obj", kIdentity, limits).ok());

  // An inline triangle first, then the file: 4 > 3.
  const std::string json = R"({"scene": {"materials": [{"name": "m"}], "meshes": [
      {"positions": [0,0,0, 1,0,0, 0,1,0], "indices": [0,1,2], "material": "m"},
      {"file": "scene.obj", "material": "m"}]},
      "grid": {"min": [0, 0, 0], "max": [0, 0, 0], "counts": [1, 1, 1]}})";
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  ASSERT_TRUE(job.ok()) << job.status();
  EXPECT_TRUE(HasFieldError(BuildBakeJob(*job, LocalAssetSource(dir.path()), limits).status(),
                            "scene.meshes[1].file", "exceed the limit of 3"));
}

absl::StatusOr<BakeJob> BuildInline(const std::string& positions, const std::string& indices,
                                    const std::string& transform = kIdentity) {
  const std::string json =
      R"({"scene": {"materials": [{"name": "m"}], "meshes": [{"positions": )" + positions +
      R"(, "indices": )" + indices + R"(, "material": "m", "transform": )" + transform +
      R"(}]}, "grid": {"min": [0, 0, 0], "max": [0, 0, 0], "counts": [1, 1, 1]}})";
  const absl::StatusOr<v1::JobSpec> job = ParseJobJson(json);
  EXPECT_TRUE(job.ok()) << job.status();
  if (!job.ok()) return job.status();
  return BuildBakeJob(*job, LocalAssetSource(""), {});
}

TEST(MeshImport, ZeroAreaTrianglesAreDropped) {
  // Triangle 0 is fine; 1 repeats a vertex; 2 is collinear (vertex 3 lies on edge 0-1).
  const absl::StatusOr<BakeJob> built =
      BuildInline("[0,0,0, 1,0,0, 0,1,0, 0.5,0,0]", "[0,1,2, 0,0,1, 0,1,3]");
  ASSERT_TRUE(built.ok()) << built.status();
  const TriangleMesh& mesh = built->scene.meshes[0];
  ASSERT_EQ(mesh.TriangleCount(), 1u);
  EXPECT_EQ(std::vector<uint32_t>(mesh.indices.begin(), mesh.indices.end()),
            (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_TRUE(HasFieldError(BuildInline("[0,0,0, 1,0,0, 2,0,0]", "[0,1,2, 2,1,0]").status(),
                            "scene.meshes[0]", "no triangle with a non-zero area"));
}

// docs/job-format.md: a scene translated by 1e4 keeps its positions in double. 0.1 + 1e4 in float
// would be 10000.099609375; in double it is the double nearest to 10000.1.
TEST(MeshImport, TranslatedSceneKeepsDoublePrecision) {
  const absl::StatusOr<BakeJob> built =
      BuildInline("[0.1,0.2,0.3, 1.1,0.2,0.3, 0.1,1.2,0.3]", "[0,1,2]",
                  "[1,0,0,10000, 0,1,0,-10000, 0,0,1,10000, 0,0,0,1]");
  ASSERT_TRUE(built.ok()) << built.status();
  const std::vector<Vec3d>& p = built->scene.meshes[0].positions;
  ASSERT_EQ(p.size(), 3u);
  const double x = 0.1, y = 0.2, z = 0.3;
  EXPECT_EQ(p[0], Vec3d(x + 10000, y - 10000, z + 10000));
  EXPECT_EQ(p[1].x, 1.1 + 10000);
  EXPECT_EQ(p[2].y, 1.2 - 10000);
  EXPECT_NE(p[0].x, double(float(x) + 10000.0f));
  // Edge vectors agree with the untranslated edges to double rounding of the translation:
  // |error| <= ulp(1e4) = 1.8e-12.
  EXPECT_NEAR(p[1].x - p[0].x, 1.0, 2e-12);

  // File meshes: the file's single-precision vertices (as assimp parsed them: the untranslated
  // import), then the translation in double.
  TempDir dir;
  dir.Write("t.obj", "v 0.1 0.2 0.3\nv 1.1 0.2 0.3\nv 0.1 1.2 0.3\nf 1 2 3\n");
  const absl::StatusOr<BakeJob> atOrigin = BuildMeshJob(dir, "t.obj");
  const absl::StatusOr<BakeJob> moved =
      BuildMeshJob(dir, "t.obj", "[1,0,0,10000, 0,1,0,-10000, 0,0,1,10000, 0,0,0,1]");
  ASSERT_TRUE(atOrigin.ok()) << atOrigin.status();
  ASSERT_TRUE(moved.ok()) << moved.status();
  const std::vector<Vec3d>& o = atOrigin->scene.meshes[0].positions;
  const std::vector<Vec3d>& q = moved->scene.meshes[0].positions;
  ASSERT_EQ(o.size(), q.size());
  EXPECT_NEAR(o[0].x, 0.1, 1e-8);  // the file's value, to float precision
  for (size_t i = 0; i < o.size(); ++i)
    EXPECT_EQ(q[i], Vec3d(o[i].x + 10000, o[i].y - 10000, o[i].z + 10000)) << i;
  EXPECT_NE(q[0].x, double(float(o[0].x) + 10000.0f));
}

}  // namespace
}  // namespace probebake
