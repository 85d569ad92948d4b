// End-to-end tests with the real executables: probebake-server (real tracer, real volume
// writer) started by the test on a free loopback port with its own data folder, and the
// probebake CLI run as a user would. Small jobs (18 to 64 probes, few samples) keep it fast.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <random>
#include <thread>

#include "client/client.h"
#include "probebake/job/digest.h"
#include "probebake/job/job_json.h"
#include "probebake/volume/vdb_io.h"
#include "server/checkpoint.h"
#include "subprocess.h"
#include "test_server.h"
#include "volume_compare.h"

namespace probebake::testing {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using std::chrono::steady_clock;

const std::string kCli = PROBEBAKE_CLI;
const std::string kServer = PROBEBAKE_SERVER;
const std::filesystem::path kData = PROBEBAKE_SERVER_TEST_DATA;

// A job file in `dir`: the box scene of data/small_job.json with the given grid counts and
// samples (box.obj copied beside it, so the file reference is uploaded by the CLI).
std::filesystem::path WriteJob(const std::filesystem::path& dir, const std::string& name, int nx,
                               int ny, int nz, int samples, int seed = 7) {
  std::filesystem::copy_file(kData / "box.obj", dir / "box.obj",
                             std::filesystem::copy_options::overwrite_existing);
  std::string json = ReadFile(kData / "small_job.json");
  auto replace = [&](const std::string& from, const std::string& to) {
    size_t at = json.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) json.replace(at, from.size(), to);
  };
  replace("\"counts\": [3, 3, 2]", "\"counts\": [" + std::to_string(nx) + ", " +
                                       std::to_string(ny) + ", " + std::to_string(nz) + "]");
  replace("\"samplesPerProbe\": 64", "\"samplesPerProbe\": " + std::to_string(samples));
  replace("\"seed\": 7", "\"seed\": " + std::to_string(seed));
  std::filesystem::path path = dir / name;
  std::ofstream(path) << json;
  return path;
}

class ServerProcess {
 public:
  ServerProcess(const std::filesystem::path& dir, std::vector<std::string> extra = {}) : dir_(dir) {
    std::filesystem::path portFile = dir / ("port" + std::to_string(++counter_));
    std::vector<std::string> argv = {
        kServer,       "--listen",       "127.0.0.1:0", "--data-dir", (dir / "data").string(),
        "--port-file", portFile.string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    process_ = std::make_unique<Subprocess>(argv, dir / "server.log");
    auto port = WaitForPortFile(portFile, seconds(30));
    EXPECT_TRUE(port) << ReadFile(dir / "server.log");
    port_ = port.value_or(0);
  }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  Subprocess& process() { return *process_; }
  std::string log() const { return ReadFile(dir_ / "server.log"); }

 private:
  static inline int counter_ = 0;
  std::filesystem::path dir_;
  std::unique_ptr<Subprocess> process_;
  int port_ = 0;
};

RunResult Cli(std::vector<std::string> args, const std::map<std::string, std::string>& env = {}) {
  args.insert(args.begin(), kCli);
  return Run(args, env, seconds(120));
}

std::string JobName(const std::string& submitOut) {
  size_t at = submitOut.find("bakeJobs/");
  return at == std::string::npos ? "" : submitOut.substr(at, 9 + 16);
}

TEST(EndToEnd, ServerBakeIsBitIdenticalToLocalBake) {
  TempDir dir;
  auto job = WriteJob(dir.path(), "job.json", 3, 3, 2, 64);
  RunResult local = Cli({"bake", job.string(), "-o", (dir.path() / "local.vdb").string()});
  ASSERT_EQ(local.exitCode, 0) << local.err;

  ServerProcess server(dir.path(), {"--threads", "1"});
  auto start = steady_clock::now();
  RunResult submit = Cli({"submit", job.string(), "--server", server.address(), "--wait", "-o",
                          (dir.path() / "server.vdb").string()});
  double submitSeconds = SecondsSince(start);
  ASSERT_EQ(submit.exitCode, 0) << submit.err << server.log();
  ExpectSameVolume(dir.path() / "local.vdb", dir.path() / "server.vdb");
  std::printf("submit --wait -o (upload, 18 probes, fetch): %.3f s\n", submitSeconds);

  // The same job again: the result cache answers, with the same volume.
  RunResult again = Cli({"submit", job.string(), "--server", server.address(), "--json"});
  ASSERT_EQ(again.exitCode, 0) << again.err;
  EXPECT_NE(again.out.find("\"cachedResult\":true"), std::string::npos) << again.out;
  // --skip-cache bakes again: same grids.
  RunResult forced = Cli({"submit", job.string(), "--server", server.address(), "--skip-cache",
                          "-o", (dir.path() / "forced.vdb").string()});
  ASSERT_EQ(forced.exitCode, 0) << forced.err;
  ExpectSameVolume(dir.path() / "local.vdb", dir.path() / "forced.vdb");

  // status / list / inspect.
  std::string name = JobName(submit.out);
  ASSERT_FALSE(name.empty()) << submit.out;
  RunResult status = Cli({"status", name, "--server", server.address()});
  EXPECT_EQ(status.exitCode, 0);
  EXPECT_NE(status.out.find("SUCCEEDED"), std::string::npos) << status.out;
  RunResult list = Cli({"list", "--server", server.address(), "--json"});
  EXPECT_EQ(list.exitCode, 0);
  EXPECT_EQ(std::count(list.out.begin(), list.out.end(), '\n'), 3) << list.out;
  RunResult inspect = Cli({"inspect", (dir.path() / "server.vdb").string(), "--json"});
  EXPECT_EQ(inspect.exitCode, 0) << inspect.err;
  EXPECT_NE(inspect.out.find("\"probes\":18"), std::string::npos) << inspect.out;
  auto png = dir.path() / "slice.png";
  RunResult slice = Cli(
      {"inspect", (dir.path() / "server.vdb").string(), "--slice", "z=1.5", "-o", png.string()});
  EXPECT_EQ(slice.exitCode, 0) << slice.err;
  EXPECT_EQ(ReadFile(png).substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  RunResult badSlice =
      Cli({"inspect", (dir.path() / "server.vdb").string(), "--slice", "w=1", "-o", png.string()});
  EXPECT_EQ(badSlice.exitCode, 2);
  EXPECT_NE(badSlice.err.find("slice"), std::string::npos) << badSlice.err;
  server.process().Signal(SIGTERM);
  EXPECT_EQ(server.process().Wait(seconds(10)), 0);
}

TEST(EndToEnd, AGridShardedAcrossALocalBakeAndAServerMergesIntoTheWholeBake) {
  // Sharding a grid across machines does not change a result (docs/job-format.md, `grid`;
  // docs/volume-format.md, "Merging sharded bakes"). The whole 3x3x2 grid baked locally; its
  // z = 0.5 layer baked locally too, its z = 2.5 layer on the server; `probebake merge` of the two
  // gives the whole volume, bit for bit.
  TempDir dir;
  auto whole = WriteJob(dir.path(), "whole.json", 3, 3, 2, 64);
  const std::string json = ReadFile(whole);
  auto writeLayer = [&](const std::string& name, const std::string& z) {
    std::string layer = json;
    const std::string from = R"("min": [-2, -2, 0.5], "max": [2, 2, 2.5], "counts": [3, 3, 2])";
    const size_t at = layer.find(from);
    EXPECT_NE(at, std::string::npos) << layer;
    if (at != std::string::npos)
      layer.replace(
          at, from.size(),
          "\"min\": [-2, -2, " + z + "], \"max\": [2, 2, " + z + "], \"counts\": [3, 3, 1]");
    std::ofstream(dir.path() / name) << layer;
    return (dir.path() / name).string();
  };
  const std::string low = writeLayer("low.json", "0.5"), high = writeLayer("high.json", "2.5");
  const std::string wholeVdb = (dir.path() / "whole.vdb").string(),
                    lowVdb = (dir.path() / "low.vdb").string(),
                    highVdb = (dir.path() / "high.vdb").string(),
                    merged = (dir.path() / "merged.vdb").string();
  ASSERT_EQ(Cli({"bake", whole.string(), "-o", wholeVdb}).exitCode, 0);
  ASSERT_EQ(Cli({"bake", low, "-o", lowVdb}).exitCode, 0);
  ServerProcess server(dir.path(), {"--threads", "1"});
  RunResult submit = Cli({"submit", high, "--server", server.address(), "-o", highVdb});
  ASSERT_EQ(submit.exitCode, 0) << submit.err << server.log();

  RunResult merge = Cli({"merge", "-o", merged, highVdb, lowVdb});
  ASSERT_EQ(merge.exitCode, 0) << merge.err;
  ExpectSameVolume(wholeVdb, merged);

  // Parts of different bakes are refused, the part and the field named.
  auto reseeded = WriteJob(dir.path(), "reseeded.json", 3, 3, 2, 64, /*seed=*/8);
  const std::string reseededVdb = (dir.path() / "reseeded.vdb").string();
  ASSERT_EQ(Cli({"bake", reseeded.string(), "-o", reseededVdb}).exitCode, 0);
  RunResult mixed = Cli({"merge", "-o", (dir.path() / "mixed.vdb").string(), lowVdb, reseededVdb});
  EXPECT_EQ(mixed.exitCode, 2);
  EXPECT_NE(mixed.err.find("part 1 (" + reseededVdb + "): seed"), std::string::npos) << mixed.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "mixed.vdb"));
  server.process().Signal(SIGTERM);
  EXPECT_EQ(server.process().Wait(seconds(10)), 0);
}

// A floor quad as a .gltf (z = 0, 20 x 20) whose buffer is the separate file `bin` and whose
// base colour texture is `image`, with base colour factor `grey` and metallic 0.
std::string FloorGltf(const std::string& bin, const std::string& image, double grey) {
  return R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
    "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
    "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [)" +
         std::to_string(grey) + "," + std::to_string(grey) + "," + std::to_string(grey) +
         R"(, 1], "metallicFactor": 0, "baseColorTexture": {"index": 0}}}],
    "textures": [{"source": 0}], "images": [{"uri": ")" +
         image + R"("}],
    "buffers": [{"uri": ")" +
         bin + R"(", "byteLength": 60}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                    {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
    "accessors": [
      {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
       "min": [-10, -10, 0], "max": [10, 10, 0]},
      {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]})";
}

std::string FloorBin() {
  const float positions[12] = {-10, -10, 0, 10, -10, 0, 10, 10, 0, -10, 10, 0};
  const uint16_t indices[6] = {0, 1, 2, 0, 2, 3};
  std::string bin(reinterpret_cast<const char*>(positions), sizeof positions);
  bin.append(reinterpret_cast<const char*>(indices), sizeof indices);
  return bin;
}

TEST(EndToEnd, AGltfWithExternalFilesBakesTheSameThroughTheServerAndUploadsEachFileOnce) {
  TempDir dir;
  std::filesystem::create_directories(dir.path() / "models" / "textures");
  std::ofstream(dir.path() / "models" / "floor.bin", std::ios::binary) << FloorBin();
  // A 2 x 2 mid-grey PNG: decoded and sampled on both sides alike.
  static const char kGreyPng[] =
      "\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x02"
      "\x00\x00\x00\x02\x08\x02\x00\x00\x00\xfd\xd4\x9a\x73\x00\x00\x00\x0e\x49\x44\x41\x54"
      "\x78\x9c\x63\x68\x00\x03\x06\x08\x05\x00\x2a\x0e\x06\x01\x15\x9e\x42\xd7\x00\x00"
      "\x00\x00\x49\x45\x4e\x44\xae\x42\x60\x82";
  std::ofstream(dir.path() / "models" / "textures" / "grey.png", std::ios::binary)
      << std::string(kGreyPng, sizeof kGreyPng - 1);
  // Two models sharing the buffer and the texture: 4 distinct files.
  std::ofstream(dir.path() / "models" / "a.gltf")
      << FloorGltf("floor.bin", "textures/grey.png", 0.5);
  std::ofstream(dir.path() / "models" / "b.gltf")
      << FloorGltf("./floor.bin", "textures/../textures/grey.png", 0.25);
  const std::filesystem::path job = dir.path() / "job.json";
  std::ofstream(job) << R"({
  "scene": {
    "meshes": [{"file": "models/a.gltf"},
               {"file": "models/b.gltf", "transform": [1,0,0,0, 0,1,0,0, 0,0,1,3, 0,0,0,1]}],
    "lights": [{"point": {"position": [0.5, 0.5, 1.5], "intensity": [5, 5, 5]}}]
  },
  "grid": {"min": [-1, -1, 0.5], "max": [1, 1, 2.5], "counts": [2, 2, 2], "placement": "ALL"},
  "settings": {"shOrder": 1, "samplesPerProbe": 32, "maxDepth": 3, "seed": 5, "irradiance": true}
})";
  RunResult local = Cli({"bake", job.string(), "-o", (dir.path() / "local.vdb").string()});
  ASSERT_EQ(local.exitCode, 0) << local.err;
  ServerProcess server(dir.path(), {"--threads", "1"});
  // The upload summary is an info line.
  RunResult submit = Cli({"--log-level", "info", "submit", job.string(), "--server",
                          server.address(), "--wait", "-o", (dir.path() / "server.vdb").string()});
  ASSERT_EQ(submit.exitCode, 0) << submit.err << server.log();
  ExpectSameVolume(dir.path() / "local.vdb", dir.path() / "server.vdb");
  EXPECT_NE(submit.err.find("4 file(s): 4 uploaded"), std::string::npos) << submit.err;
  // A missing texture is refused both ways, naming the mesh's field and the path the model wrote.
  std::filesystem::remove(dir.path() / "models" / "textures" / "grey.png");
  RunResult missingLocal = Cli({"bake", job.string(), "-o", (dir.path() / "m.vdb").string()});
  RunResult missingServer = Cli({"submit", job.string(), "--server", server.address()});
  for (const RunResult* r : {&missingLocal, &missingServer}) {
    EXPECT_EQ(r->exitCode, 2) << r->err;
    EXPECT_NE(r->err.find("scene.meshes[0].file: \"models/a.gltf\" references "
                          "\"textures/grey.png\": cannot read it"),
              std::string::npos)
        << r->err;
  }
  server.process().Signal(SIGTERM);
  EXPECT_EQ(server.process().Wait(seconds(10)), 0);
}

TEST(EndToEnd, CliExitCodes) {
  TempDir dir;
  auto job = WriteJob(dir.path(), "job.json", 2, 2, 1, 16);
  // 2: bad input, the message names the file and the field.
  std::ofstream(dir.path() / "unknown.json") << R"({"grid": {"min": [0,0,0], "max": [1,1,1],
      "counts": [1,1,1]}, "settings": {"samplesPerProbe": 4, "sampels": 3}})";
  RunResult unknown =
      Cli({"bake", (dir.path() / "unknown.json").string(), "-o", (dir.path() / "x.vdb").string()});
  EXPECT_EQ(unknown.exitCode, 2);
  EXPECT_NE(unknown.err.find("unknown.json"), std::string::npos) << unknown.err;
  EXPECT_NE(unknown.err.find("settings.sampels"), std::string::npos) << unknown.err;
  // 2: an output path that cannot be written fails before the bake, so a mistyped -o costs no
  // baking: no progress line is printed (a bake that ran prints at least its final one).
  const std::string unwritablePath = (dir.path() / "missing" / "x.vdb").string();
  RunResult unwritable = Cli({"bake", job.string(), "-o", unwritablePath, "--json"});
  EXPECT_EQ(unwritable.exitCode, 2);
  EXPECT_NE(unwritable.err.find(unwritablePath), std::string::npos) << unwritable.err;
  EXPECT_EQ(unwritable.out, "") << "the bake ran before its output path was checked";
  RunResult intoDirectory = Cli({"bake", job.string(), "-o", dir.path().string(), "--json"});
  EXPECT_EQ(intoDirectory.exitCode, 2);
  EXPECT_NE(intoDirectory.err.find("is a directory"), std::string::npos) << intoDirectory.err;
  EXPECT_EQ(intoDirectory.out, "");
  RunResult usage = Cli({"bake"});
  EXPECT_EQ(usage.exitCode, 2);
  RunResult noCommand = Cli({});
  EXPECT_EQ(noCommand.exitCode, 2);
  // 4: nothing listens there (a port just freed).
  RunResult unreachable = Cli({"status", "bakeJobs/0123456789abcdef", "--server", "127.0.0.1:1"});
  EXPECT_EQ(unreachable.exitCode, 4) << unreachable.err;

  std::ofstream(dir.path() / "token") << "e2e-token\n";
  ServerProcess server(dir.path(), {"--token-file", (dir.path() / "token").string()});
  // 4: no token, a wrong token.
  RunResult noToken = Cli({"list", "--server", server.address()});
  EXPECT_EQ(noToken.exitCode, 4) << noToken.err;
  RunResult badToken = Cli({"list", "--server", server.address()}, {{"PROBEBAKE_TOKEN", "nope"}});
  EXPECT_EQ(badToken.exitCode, 4) << badToken.err;
  std::map<std::string, std::string> env = {{"PROBEBAKE_TOKEN", "e2e-token"},
                                            {"PROBEBAKE_SERVER", server.address()}};
  // 2 from the server: a job past a limit, and a missing file, both naming file and field.
  auto huge = WriteJob(dir.path(), "huge.json", 3000, 3000, 1000, 16);
  RunResult tooBig = Cli({"submit", huge.string()}, env);
  EXPECT_EQ(tooBig.exitCode, 2);
  EXPECT_NE(tooBig.err.find("huge.json: grid"), std::string::npos) << tooBig.err;
  std::filesystem::remove(dir.path() / "box.obj");
  RunResult missing = Cli({"submit", job.string()}, env);
  EXPECT_EQ(missing.exitCode, 2);
  EXPECT_NE(missing.err.find("scene.meshes[0].file"), std::string::npos) << missing.err;
  job = WriteJob(dir.path(), "job.json", 2, 2, 1, 16);
  // 2: an unknown job name, a malformed one.
  EXPECT_EQ(Cli({"status", "bakeJobs/0123456789abcdef"}, env).exitCode, 2);
  EXPECT_EQ(Cli({"status", "nonsense"}, env).exitCode, 2);

  // 0, then 3 for a cancelled job: a long bake (64 probes x 1M samples), cancelled.
  auto slow = WriteJob(dir.path(), "slow.json", 4, 4, 4, 1 << 20);
  RunResult queued = Cli({"submit", slow.string()}, env);
  ASSERT_EQ(queued.exitCode, 0) << queued.err;
  std::string name = JobName(queued.out);
  for (int i = 0; i < 200; ++i) {
    if (Cli({"status", name}, env).out.find("RUNNING") != std::string::npos) break;
    std::this_thread::sleep_for(milliseconds(20));
  }
  auto start = steady_clock::now();
  RunResult cancel = Cli({"cancel", name}, env);
  double cancelSeconds = SecondsSince(start);
  EXPECT_EQ(cancel.exitCode, 0) << cancel.err;
  EXPECT_NE(cancel.out.find("CANCELLED"), std::string::npos) << cancel.out;
  std::printf("probebake cancel (request to CANCELLED, process included): %.3f s\n", cancelSeconds);
  EXPECT_EQ(Cli({"status", name}, env).exitCode, 3);
  EXPECT_EQ(Cli({"watch", name}, env).exitCode, 3);
  RunResult fetchCancelled = Cli({"fetch", name, "-o", (dir.path() / "c.vdb").string()}, env);
  EXPECT_EQ(fetchCancelled.exitCode, 3);
  // delete: 0, then the job is unknown (2), as is deleting it again.
  RunResult deleted = Cli({"delete", name}, env);
  EXPECT_EQ(deleted.exitCode, 0) << deleted.err;
  EXPECT_EQ(deleted.out, name + " deleted\n");
  EXPECT_EQ(Cli({"status", name}, env).exitCode, 2);
  RunResult deletedAgain = Cli({"delete", name}, env);
  EXPECT_EQ(deletedAgain.exitCode, 2);
  EXPECT_NE(deletedAgain.err.find("no such job"), std::string::npos) << deletedAgain.err;
  // 0: a good job, watched, fetched.
  RunResult good =
      Cli({"submit", job.string(), "--wait", "-o", (dir.path() / "g.vdb").string()}, env);
  EXPECT_EQ(good.exitCode, 0) << good.err;
  server.process().Signal(SIGTERM);
  EXPECT_EQ(server.process().Wait(seconds(10)), 0);
}

// What a server refuses is reported as the user wrote the job: the field and file, not the blob
// the CLI uploaded for it; and inputs that once crashed or hung a server leave it serving.
TEST(EndToEnd, CliNamesWhatItAndTheServerRefuse) {
  TempDir dir;
  const std::filesystem::path job = WriteJob(dir.path(), "job.json", 2, 2, 1, 16);
  // 2, not 4: an address that cannot name a server.
  RunResult garbage = Cli({"list", "--server", "garbage:::"});
  EXPECT_EQ(garbage.exitCode, 2) << garbage.err;
  EXPECT_NE(garbage.err.find("--server: \"garbage:::\" is not HOST:PORT"), std::string::npos)
      << garbage.err;
  RunResult badPort = Cli({"list"}, {{"PROBEBAKE_SERVER", "127.0.0.1:99999"}});
  EXPECT_EQ(badPort.exitCode, 2) << badPort.err;
  EXPECT_NE(badPort.err.find("$PROBEBAKE_SERVER"), std::string::npos) << badPort.err;

  ServerProcess server(dir.path());
  const std::map<std::string, std::string> env = {{"PROBEBAKE_SERVER", server.address()}};
  const std::string base = ReadFile(job);
  auto variant = [&](const std::string& name, const std::string& meshFile) {
    std::string json = base;
    json.replace(json.find("\"box.obj\""), 9, "\"" + meshFile + "\"");
    std::ofstream(dir.path() / name) << json;
    return (dir.path() / name).string();
  };
  // A folder named as a mesh file is refused, not uploaded as an empty blob.
  std::filesystem::create_directory(dir.path() / "folder.obj");
  RunResult folder = Cli({"submit", variant("folder.json", "folder.obj")}, env);
  EXPECT_EQ(folder.exitCode, 2) << folder.err;
  EXPECT_NE(folder.err.find("scene.meshes[0].file: cannot read \"folder.obj\""), std::string::npos)
      << folder.err;
  EXPECT_NE(folder.err.find("not a regular file"), std::string::npos) << folder.err;
  // The server's import error names the file as written.
  std::ofstream(dir.path() / "bad.ply") << "ply\nformat ascii 1.0\nelement vertex 3\n";
  RunResult bad = Cli({"submit", variant("bad.json", "bad.ply")}, env);
  EXPECT_EQ(bad.exitCode, 2) << bad.err;
  EXPECT_NE(bad.err.find("bad.json: scene.meshes[0].file: cannot import \"bad.ply\" as ply: its "
                         "header has no end_header line"),
            std::string::npos)
      << bad.err;
  EXPECT_EQ(bad.err.find("blob"), std::string::npos) << bad.err;
  // A NUL byte in a PLY header crashed the server (assimp); it must still answer afterwards.
  std::ofstream(dir.path() / "nul.ply", std::ios::binary)
      << std::string("ply\nformat binary_little_endian 1.0\nelement vertex 3\n\0end_header\n", 65);
  RunResult nul = Cli({"submit", variant("nul.json", "nul.ply")}, env);
  EXPECT_EQ(nul.exitCode, 2) << nul.err;
  EXPECT_NE(nul.err.find("not text"), std::string::npos) << nul.err;
  EXPECT_EQ(Cli({"list"}, env).exitCode, 0);

  // Files that crash assimp past every structural check (data/line_loop_one_index.gltf, from
  // fuzzing: a LINE_LOOP of one index aborts assimp 5.2) are imported in a child first, by the
  // server and by a local bake: either way a clean refusal naming the field, never a dead process.
  std::filesystem::copy_file(kData / "line_loop_one_index.gltf", dir.path() / "loop.gltf");
  const std::string loopJob = variant("loop.json", "loop.gltf");
  RunResult loopServer = Cli({"submit", loopJob}, env);
  EXPECT_EQ(loopServer.exitCode, 2) << loopServer.err;
  EXPECT_NE(loopServer.err.find("loop.json: scene.meshes[0].file: "), std::string::npos)
      << loopServer.err;
  EXPECT_EQ(Cli({"list"}, env).exitCode, 0);
  RunResult loopLocal = Cli({"bake", loopJob, "-o", (dir.path() / "loop.vdb").string()});
  EXPECT_EQ(loopLocal.exitCode, 2) << loopLocal.err;
  EXPECT_NE(loopLocal.err.find("loop.json: scene.meshes[0].file: "), std::string::npos)
      << loopLocal.err;

  // A job too large for one request message: refused by the CLI, naming the culprit.
  std::string positions = "0,0,0";
  for (int i = 1; i < 200000; ++i) positions += ",0.123456789,0.987654321," + std::to_string(i);
  std::string huge = base;
  const std::string from = R"("positions": [)";
  huge.replace(huge.find(from) + from.size(),
               huge.find(']', huge.find(from)) - huge.find(from) - from.size(), positions);
  std::ofstream(dir.path() / "huge.json") << huge;
  RunResult tooLarge = Cli({"submit", (dir.path() / "huge.json").string()}, env);
  EXPECT_EQ(tooLarge.exitCode, 2) << tooLarge.err;
  EXPECT_NE(tooLarge.err.find("over the server's message limit"), std::string::npos)
      << tooLarge.err;
  EXPECT_NE(tooLarge.err.find("scene.meshes[1]"), std::string::npos) << tooLarge.err;

  server.process().Signal(SIGTERM);
  EXPECT_EQ(server.process().Wait(seconds(10)), 0);
}

TEST(EndToEnd, TlsWithToken) {
  TempDir dir;
  auto cert = dir.path() / "cert.pem", key = dir.path() / "key.pem";
  RunResult made = testing::Run({"/usr/bin/openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt",
                                 "ec_paramgen_curve:prime256v1", "-nodes", "-keyout", key.string(),
                                 "-out", cert.string(), "-days", "1", "-subj", "/CN=localhost",
                                 "-addext", "subjectAltName=IP:127.0.0.1,DNS:localhost"});
  if (made.exitCode != 0) GTEST_SKIP() << "openssl could not make a certificate: " << made.err;
  std::ofstream(dir.path() / "token") << "tls-token\n";
  ServerProcess server(dir.path(), {"--tls-cert", cert.string(), "--tls-key", key.string(),
                                    "--token-file", (dir.path() / "token").string()});
  std::map<std::string, std::string> env = {{"PROBEBAKE_TOKEN", "tls-token"}};
  RunResult ok = Cli({"list", "--server", server.address(), "--tls-ca", cert.string()}, env);
  EXPECT_EQ(ok.exitCode, 0) << ok.err;
  // Plaintext to a TLS server, and TLS with roots that do not trust the certificate: 4.
  EXPECT_EQ(Cli({"list", "--server", server.address()}, env).exitCode, 4);
  EXPECT_EQ(Cli({"list", "--server", server.address(), "--tls"}, env).exitCode, 4);
  // TLS without the token: 4.
  EXPECT_EQ(Cli({"list", "--server", server.address(), "--tls-ca", cert.string()}).exitCode, 4);
  // A job over TLS.
  auto job = WriteJob(dir.path(), "job.json", 2, 2, 1, 16);
  RunResult submit = Cli({"submit", job.string(), "--server", server.address(), "--tls-ca",
                          cert.string(), "-o", (dir.path() / "tls.vdb").string()},
                         env);
  EXPECT_EQ(submit.exitCode, 0) << submit.err;
}

TEST(EndToEnd, FetchResumesOnlyItsOwnPartialDownloadAndRejectsACorruptOne) {
  TempDir dir;
  auto job = WriteJob(dir.path(), "job.json", 3, 3, 2, 64);
  ServerProcess server(dir.path());
  RunResult submit = Cli({"submit", job.string(), "--server", server.address(), "--wait"});
  ASSERT_EQ(submit.exitCode, 0) << submit.err;
  std::string name = JobName(submit.out);
  auto full = dir.path() / "full.vdb";
  ASSERT_EQ(Cli({"fetch", name, "--server", server.address(), "-o", full.string()}).exitCode, 0);
  std::string bytes = ReadFile(full);
  ASSERT_GT(bytes.size(), 1000u);
  // A download broken after 1000 bytes continues from there.
  auto out = dir.path() / "resumed.vdb";
  const std::string partSuffix = "." + Sha256Hex(bytes).substr(0, 12) + ".part";
  std::ofstream(out.string() + partSuffix, std::ios::binary) << bytes.substr(0, 1000);
  RunResult resumed = Cli({"fetch", name, "--server", server.address(), "-o", out.string()});
  ASSERT_EQ(resumed.exitCode, 0) << resumed.err;
  EXPECT_EQ(ReadFile(out), bytes);
  EXPECT_FALSE(std::filesystem::exists(out.string() + partSuffix));
  // A partial file with wrong bytes fails the digest check, is removed, and a retry succeeds.
  auto bad = dir.path() / "bad.vdb";
  std::string wrong = bytes.substr(0, 1000);
  wrong[10] ^= 0x55;
  std::ofstream(bad.string() + partSuffix, std::ios::binary) << wrong;
  RunResult corrupt = Cli({"fetch", name, "--server", server.address(), "-o", bad.string()});
  EXPECT_NE(corrupt.exitCode, 0);
  EXPECT_NE(corrupt.err.find("hashes to"), std::string::npos) << corrupt.err;
  EXPECT_FALSE(std::filesystem::exists(bad));
  EXPECT_FALSE(std::filesystem::exists(bad.string() + partSuffix));
  EXPECT_EQ(Cli({"fetch", name, "--server", server.address(), "-o", bad.string()}).exitCode, 0);
  EXPECT_EQ(ReadFile(bad), bytes);
  // Partial files of other downloads to the same path (an interrupted fetch of another job, the
  // old naming) are not taken up: the first fetch succeeds.
  auto other = dir.path() / "other.vdb";
  std::ofstream(other.string() + ".part", std::ios::binary) << std::string(1000, 'x');
  std::ofstream(other.string() + ".0123456789ab.part", std::ios::binary) << std::string(1000, 'y');
  RunResult first = Cli({"fetch", name, "--server", server.address(), "-o", other.string()});
  ASSERT_EQ(first.exitCode, 0) << first.err;
  EXPECT_EQ(ReadFile(other), bytes);
  // A second fetch to a path another is downloading to fails at once (exit 1) and leaves the
  // other's partial file alone.
  auto busy = dir.path() / "busy.vdb";
  std::ofstream(busy.string() + partSuffix, std::ios::binary) << bytes.substr(0, 1000);
  const int held = ::open((busy.string() + partSuffix).c_str(), O_RDWR);
  ASSERT_GE(held, 0);
  ASSERT_EQ(::flock(held, LOCK_EX | LOCK_NB), 0);
  RunResult second = Cli({"fetch", name, "--server", server.address(), "-o", busy.string()});
  EXPECT_EQ(second.exitCode, 1) << second.err;
  EXPECT_NE(second.err.find("another fetch is downloading to"), std::string::npos) << second.err;
  EXPECT_EQ(ReadFile(busy.string() + partSuffix), bytes.substr(0, 1000));
  ::close(held);
  // A directory as the output is refused before the download (exit 2), writing nothing.
  RunResult intoDir = Cli({"fetch", name, "--server", server.address(), "-o", dir.path().string()});
  EXPECT_EQ(intoDir.exitCode, 2) << intoDir.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path().string() + partSuffix));
  // A volume the server lost (its file removed behind its back) is the server's failure: exit 1,
  // not 2 (bad input), and the message names the job.
  int removed = 0;
  for (const auto& entry :
       std::filesystem::recursive_directory_iterator(dir.path() / "data" / "blobs"))
    if (entry.is_regular_file() && ReadFile(entry.path()) == bytes)
      removed += int(std::filesystem::remove(entry.path()));
  ASSERT_EQ(removed, 1);
  RunResult lost =
      Cli({"fetch", name, "--server", server.address(), "-o", (dir.path() / "lost.vdb").string()});
  EXPECT_EQ(lost.exitCode, 1) << lost.err;
  EXPECT_NE(lost.err.find(name + ": the server no longer has its volume"), std::string::npos)
      << lost.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / ("lost.vdb" + partSuffix)));  // none began
}

TEST(EndToEnd, KilledMidBakeTheJobCompletesOnceWithTheSameBits) {
  TempDir dir;
  // 75 probes x 12288 samples: a few seconds of baking on two cores. (Counts giving spacings
  // that are exact in binary: 5 x 5 x 3 over the box's 4 x 4 x 2 grid.)
  auto job = WriteJob(dir.path(), "job.json", 5, 5, 3, 12288, 5);
  RunResult local = Cli({"bake", job.string(), "-o", (dir.path() / "local.vdb").string()});
  ASSERT_EQ(local.exitCode, 0) << local.err;

  std::string name;
  int64_t doneAtKill = 0;     // probes done as the job's progress said just before the kill
  server::Checkpoint atKill;  // the checkpoint on disk when the server was killed
  {
    ServerProcess server(dir.path(), {"--checkpoint-interval", "0.2"});
    RunResult submit = Cli({"submit", job.string(), "--server", server.address()});
    ASSERT_EQ(submit.exitCode, 0) << submit.err;
    name = JobName(submit.out);
    client::ConnectOptions options;
    options.server = server.address();
    auto c = client::Client::Connect(options);
    ASSERT_TRUE(c.ok());
    // Bake publishes a tick's progress before it writes that tick's checkpoint, so probes done
    // say nothing of what is on disk: wait for a checkpoint that holds at least 8 probes, then
    // kill. (A bound of 120 s, far above the few seconds the whole bake takes on two cores.)
    const std::filesystem::path checkpointFile =
        server::CheckpointFilePath(dir.path() / "data", name);
    auto start = steady_clock::now();
    int64_t checkpointed = 0;
    while (checkpointed < 8) {
      ASSERT_LT(SecondsSince(start), 120) << "no checkpoint with 8 probes done\n" << server.log();
      auto got = (*c)->GetJob(name);
      ASSERT_TRUE(got.ok()) << got.status();
      ASSERT_NE(got->state(), v1::BakeJob::SUCCEEDED) << "the bake finished before it was killed";
      ASSERT_TRUE(got->state() == v1::BakeJob::QUEUED || got->state() == v1::BakeJob::RUNNING)
          << got->DebugString();
      doneAtKill = got->progress().probes_done();
      auto read = server::ReadCheckpointOfAnyJob(checkpointFile);
      if (read.ok()) checkpointed = read->DoneCount();
      if (checkpointed < 8) std::this_thread::sleep_for(milliseconds(20));
    }
    server.process().Signal(SIGKILL);
    EXPECT_EQ(server.process().Wait(seconds(10)), -SIGKILL);
    // Written atomically, so this is the file the restarted server resumes from (a later tick
    // may have replaced the one seen above before the kill landed).
    auto read = server::ReadCheckpointOfAnyJob(checkpointFile);
    ASSERT_TRUE(read.ok()) << read.status();
    atKill = std::move(*read);
    ASSERT_GE(atKill.DoneCount(), 8);
    ASSERT_LT(atKill.DoneCount(), 75) << "the bake finished before it was killed";
  }
  auto restart = steady_clock::now();
  ServerProcess server(dir.path(), {"--checkpoint-interval", "0.2"});
  double servingSeconds = SecondsSince(restart);
  RunResult watch = Cli({"watch", name, "--server", server.address(), "--json"});
  ASSERT_EQ(watch.exitCode, 0) << watch.err << server.log();
  double doneSeconds = SecondsSince(restart);
  RunResult status = Cli({"status", name, "--server", server.address(), "--json"});
  EXPECT_NE(status.out.find("\"attempts\":2"), std::string::npos) << status.out;
  size_t at = status.out.find("\"probesResumed\":\"");
  ASSERT_NE(at, std::string::npos) << status.out;
  int64_t resumed = std::stoll(status.out.substr(at + 17));
  EXPECT_EQ(resumed, atKill.DoneCount()) << "not resumed from the checkpoint left by the kill";
  RunResult fetch = Cli(
      {"fetch", name, "--server", server.address(), "-o", (dir.path() / "server.vdb").string()});
  ASSERT_EQ(fetch.exitCode, 0) << fetch.err;
  ExpectSameVolume(dir.path() / "local.vdb", dir.path() / "server.vdb");
  // The stats count both attempts: the first's work as its checkpoint recorded it (the work
  // the killed process did after it is lost, like the probes it finished meanwhile), then the
  // second's, which traced exactly (75 - resumed) x 12288 samples (no adaptive stop).
  auto localVolume = ReadProbeVolume((dir.path() / "local.vdb").string());
  auto baked = ReadProbeVolume((dir.path() / "server.vdb").string());
  ASSERT_TRUE(localVolume.ok() && baked.ok());
  EXPECT_EQ(localVolume->volume.stats.samples, 75 * 12288);
  EXPECT_GT(atKill.work.samples, 0) << "the checkpoint holds no work of the first attempt";
  EXPECT_EQ(baked->volume.stats.samples, atKill.work.samples + (75 - resumed) * 12288)
      << "the .vdb stats do not count the first attempt's work as checkpointed";
  EXPECT_GT(baked->volume.stats.rays, baked->volume.stats.samples);
  EXPECT_NE(status.out.find("\"samples\":\"" + std::to_string(baked->volume.stats.samples) + "\""),
            std::string::npos)
      << "the job's result stats differ from the volume's: " << status.out;
  // Exactly one job, baked by two attempts, never two at once (one server per data folder).
  RunResult list = Cli({"list", "--server", server.address()});
  EXPECT_EQ(std::count(list.out.begin(), list.out.end(), '\n'), 1) << list.out;
  std::printf(
      "killed at %lld/75 probes (progress), %lld in the checkpoint on disk; restarted server "
      "serving after %.3f s; resumed %lld probes from the checkpoint; job done %.3f s after the "
      "restart\n",
      (long long)doneAtKill, (long long)atKill.DoneCount(), servingSeconds, (long long)resumed,
      doneSeconds);
}

TEST(EndToEnd, SubmitToRunningLatencyAndFetchThroughput) {
  TempDir dir;
  ServerProcess server(dir.path());
  client::ConnectOptions options;
  options.server = server.address();
  auto c = client::Client::Connect(options);
  ASSERT_TRUE(c.ok());
  ASSERT_TRUE((*c)->GetCapabilities().ok());
  // Submit-to-running: CreateBakeJob sent until a watch reports RUNNING, median of 5 jobs.
  std::vector<double> latencies;
  for (int i = 0; i < 5; ++i) {
    std::string file = "j";  // (operator+ on strings trips GCC 12's -Wrestrict)
    file += std::to_string(i);
    file += ".json";
    std::string path = WriteJob(dir.path(), file, 2, 2, 1, 16, 100 + i).string();
    auto spec = ReadJobFile(path);
    ASSERT_TRUE(spec.ok());
    ASSERT_TRUE((*c)->UploadJobFiles(dir.path(), &*spec).ok());
    auto start = steady_clock::now();
    auto job = (*c)->CreateJob(*spec, "", false);
    ASSERT_TRUE(job.ok()) << job.status();
    double running = -1;
    auto final = (*c)->Watch(job->name(), [&](const v1::BakeJob& update) {
      if (running < 0 && update.state() >= v1::BakeJob::RUNNING) running = SecondsSince(start);
    });
    ASSERT_TRUE(final.ok());
    ASSERT_EQ(final->state(), v1::BakeJob::SUCCEEDED);
    latencies.push_back(running);
  }
  std::sort(latencies.begin(), latencies.end());
  // Fetch throughput on loopback: a 64 MiB blob uploaded, then fetched with the CLI's client.
  std::string blob(64 << 20, '\0');
  std::mt19937_64 rng(1);
  for (size_t i = 0; i + 8 <= blob.size(); i += 8) {
    uint64_t v = rng();
    std::memcpy(&blob[i], &v, 8);
  }
  v1::Digest digest = DigestOf(blob);
  auto upStart = steady_clock::now();
  ASSERT_TRUE((*c)->UploadBlob(digest, blob).ok());
  double upSeconds = SecondsSince(upStart);
  auto downStart = steady_clock::now();
  ASSERT_TRUE((*c)->FetchBlob(digest, dir.path() / "blob.bin").ok());
  double downSeconds = SecondsSince(downStart);
  EXPECT_EQ(std::filesystem::file_size(dir.path() / "blob.bin"), blob.size());
  std::printf(
      "submit-to-running: median %.1f ms (min %.1f, max %.1f); loopback upload %.0f MB/s, "
      "fetch (download + SHA-256 check) %.0f MB/s\n",
      1e3 * latencies[2], 1e3 * latencies[0], 1e3 * latencies[4],
      double(blob.size()) / 1e6 / upSeconds, double(blob.size()) / 1e6 / downSeconds);
}

}  // namespace
}  // namespace probebake::testing
