// Every OBJ, PLY, glTF and GLB file of Debian's assimp-testmodels (third-party files, many broken
// on purpose) baked by the CLI locally and submitted to a real probebake-server: each either bakes
// or is refused with a message naming the mesh's field and the reason, the same outcome both ways
// (the same bits when it bakes), and nothing crashes or hangs (each run is killed after a time
// bound). Skipped, saying why, when the package is not installed.
#include <gtest/gtest.h>

#include <signal.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>

#include "subprocess.h"
#include "temp_dir.h"
#include "volume_compare.h"

namespace probebake::testing {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;

const std::string kCli = PROBEBAKE_CLI;
const std::string kServer = PROBEBAKE_SERVER;
const fs::path kModels = "/usr/share/assimp/models";

// A small job over `model` (relative to the job file) with its own materials: 8 probes, 16 samples,
// a uniform sky.
std::string JobJson(const std::string& model) {
  return R"({
  "scene": {
    "meshes": [{"name": "model", "file": ")" +
         model + R"("}],
    "environment": {"uniform": {"radiance": [1, 1, 1]}}
  },
  "grid": {"min": [-1, -1, -1], "max": [1, 1, 1], "counts": [2, 2, 2], "placement": "ALL"},
  "settings": {"shOrder": 1, "samplesPerProbe": 16, "maxDepth": 2, "seed": 3, "irradiance": true}
})";
}

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return s;
}

// The reason of a refusal: the text after "scene.meshes[0].<field>: " on the CLI's last line
// naming it, without the file's name; "" when no line names the mesh's field.
std::string Reason(const std::string& err) {
  const size_t at = err.rfind("scene.meshes[0]");
  if (at == std::string::npos) return "";
  std::string line = err.substr(at, err.find('\n', at) - at);
  return line;
}

// The kind of a reason, for the tally: the reason with quoted names and numbers blanked.
std::string Kind(std::string reason) {
  std::string out;
  bool quoted = false;
  for (char c : reason) {
    if (c == '"') {
      quoted = !quoted;
      if (quoted) out += "\"...\"";
      continue;
    }
    if (quoted) continue;
    out += std::isdigit(static_cast<unsigned char>(c)) ? '#' : c;
  }
  return out.substr(0, 140);
}

TEST(AssimpTestModels, EachBakesOrIsRefusedNamingTheFieldTheSameLocallyAndOnTheServer) {
  if (!fs::is_directory(kModels))
    GTEST_SKIP() << kModels << " is missing: install Debian's assimp-testmodels";
  TempDir dir;
  // The models folders copied into the job folder: a model's referenced files must stay inside it.
  const fs::path root = dir.path() / "models";
  fs::copy(kModels, root, fs::copy_options::recursive | fs::copy_options::skip_symlinks);
  std::vector<fs::path> models;
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    const std::string ext = Lower(entry.path().extension().string());
    if (entry.is_regular_file() &&
        (ext == ".obj" || ext == ".ply" || ext == ".gltf" || ext == ".glb"))
      models.push_back(entry.path());
  }
  std::sort(models.begin(), models.end());
  ASSERT_GT(models.size(), 50u) << "too few models found under " << kModels;

  const fs::path portFile = dir.path() / "port";
  Subprocess server(
      {kServer, "--listen", "127.0.0.1:0", "--data-dir", (dir.path() / "data").string(),
       "--port-file", portFile.string(), "--threads", "1"},
      dir.path() / "server.log");
  const std::optional<int> port = WaitForPortFile(portFile, seconds(30));
  ASSERT_TRUE(port) << ReadFile(dir.path() / "server.log");
  const std::string address = "127.0.0.1:" + std::to_string(*port);

  int baked = 0, refused = 0;
  std::map<std::string, int> reasons;
  for (size_t i = 0; i < models.size(); ++i) {
    const fs::path& model = models[i];
    SCOPED_TRACE(model.lexically_relative(root).string());
    const fs::path job = root / ("job" + std::to_string(i) + ".json");
    std::ofstream(job) << JobJson(model.lexically_relative(root).generic_string());
    const fs::path localOut = dir.path() / ("local" + std::to_string(i) + ".vdb");
    const fs::path serverOut = dir.path() / ("server" + std::to_string(i) + ".vdb");
    const RunResult local = probebake::testing::Run(
        {kCli, "bake", job.string(), "--threads", "1", "-o", localOut.string()}, {}, seconds(120));
    const RunResult remote = probebake::testing::Run(
        {kCli, "submit", job.string(), "--server", address, "--wait", "-o", serverOut.string()}, {},
        seconds(120));
    // Exit 0: baked; 2: refused (bad input). Anything else is a crash, a hang or a failed bake.
    ASSERT_TRUE(local.exitCode == 0 || local.exitCode == 2) << local.exitCode << "\n" << local.err;
    ASSERT_EQ(remote.exitCode, local.exitCode) << "local:\n"
                                               << local.err << "\nserver:\n"
                                               << remote.err;
    if (local.exitCode == 0) {
      ++baked;
      ExpectSameVolume(localOut, serverOut);
      continue;
    }
    ++refused;
    const std::string reason = Reason(local.err);
    EXPECT_FALSE(reason.empty()) << "the refusal names no field of the mesh:\n" << local.err;
    EXPECT_EQ(Reason(remote.err), reason) << "server:\n" << remote.err;
    // A .gltf whose buffers and images are separate files present beside it bakes.
    if (Lower(model.extension().string()) == ".gltf") {
      EXPECT_EQ(reason.find("must be embedded"), std::string::npos) << reason;
    }
    ++reasons[Kind(reason)];
  }
  std::printf("assimp-testmodels: %zu files, %d baked, %d refused\n", models.size(), baked,
              refused);
  for (const auto& [kind, count] : reasons) std::printf("  %3d  %s\n", count, kind.c_str());
  server.Signal(SIGTERM);
  EXPECT_EQ(server.Wait(seconds(10)), 0);
}

}  // namespace
}  // namespace probebake::testing
