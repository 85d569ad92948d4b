// probebake relight, end to end through the command line: bake a sky transfer, relight it for a
// uniform sky given as a colour and as SH coefficients (the same sky: the same bits), and refuse
// bad usage with exit code 2.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

#include "probebake/bake/relight.h"
#include "probebake/volume/vdb_io.h"

namespace probebake {
namespace {

const std::string kCli = std::string(PROBEBAKE_BINARY_DIR) + "/bin/probebake";

// Exit code of `probebake <args>` (output to log).
int RunCli(const std::string& args, const std::string& log) {
  const int status = std::system((kCli + " " + args + " >" + log + " 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

void Write(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
}

TEST(RelightCli, UniformColourAndItsShRelightAlikeAndBadUsageIsRefused) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("probebake_relight_cli_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string d = dir.string(), log = d + "/log.txt";
  const std::string scene = R"({
    "scene": {"materials": [{"name": "grey", "albedo": [0.5, 0.4, 0.3]}],
              "meshes": [{"name": "ground", "material": "grey",
                          "positions": [-5,-5,0, 5,-5,0, 5,5,0, -5,5,0], "indices": [0,1,2, 0,2,3]}],
              "lights": [{"point": {"position": [0, 0, 2], "intensity": [3, 3, 3]}}],
              "environment": {"uniform": {"radiance": [0.2, 0.3, 0.4]}}},
    "grid": {"min": [-1, -1, 0.5], "max": [1, 1, 0.5], "counts": [2, 2, 1], "placement": "ALL"},
    "settings": {"shOrder": 2, "samplesPerProbe": 256, "irradiance": true)";
  Write(d + "/transfer.json", scene + R"(, "skyTransfer": {"order": 2}}})");
  Write(d + "/plain.json", scene + "}}");
  ASSERT_EQ(RunCli("bake " + d + "/transfer.json -o " + d + "/transfer.vdb", log), 0);
  ASSERT_EQ(RunCli("bake " + d + "/plain.json -o " + d + "/plain.vdb", log), 0);

  // The same sky three ways: a colour, its SH (L00 = 2 sqrt(pi) c) and the core function.
  ASSERT_EQ(RunCli("relight " + d + "/transfer.vdb --uniform 0.5,0.25,1 -o " + d + "/a.vdb", log),
            0);
  const double k = 2 * std::sqrt(std::acos(-1.0));
  char sh[256];
  std::snprintf(sh, sizeof sh, R"({"coefficients": [[%.17g, %.17g, %.17g]]})", 0.5 * k, 0.25 * k,
                1 * k);
  Write(d + "/sky.json", sh);
  ASSERT_EQ(
      RunCli("relight " + d + "/transfer.vdb --environment " + d + "/sky.json -o " + d + "/b.vdb",
             log),
      0);
  const absl::StatusOr<ProbeVolumeFile> a = ReadProbeVolume(d + "/a.vdb");
  const absl::StatusOr<ProbeVolumeFile> b = ReadProbeVolume(d + "/b.vdb");
  const absl::StatusOr<ProbeVolumeFile> t = ReadProbeVolume(d + "/transfer.vdb");
  ASSERT_TRUE(a.ok() && b.ok() && t.ok());
  EXPECT_EQ(a->format, kProbeVolumeFormat);
  EXPECT_EQ(a->volume.skyTransferOrder, 0);
  EXPECT_EQ(a->volume.radiance, b->volume.radiance);
  EXPECT_EQ(a->volume.irradiance, b->volume.irradiance);
  std::vector<Vec3d> sky(9);
  sky[0] = Vec3d{0.5, 0.25, 1} * k;
  const absl::StatusOr<ProbeVolume> core = Relight(t->volume, sky);
  ASSERT_TRUE(core.ok());
  EXPECT_EQ(a->volume.radiance, core->radiance);
  // The sky changed the radiance: every active probe's L00 is above the local lights' alone.
  for (size_t p = 0; p < 4; ++p)
    EXPECT_GT(a->volume.radiance[0][3 * p], t->volume.radiance[0][3 * p]);

  // Bad usage: exit code 2 with a message.
  EXPECT_EQ(RunCli("relight " + d + "/plain.vdb --uniform 1,1,1 -o " + d + "/c.vdb", log), 2);
  EXPECT_EQ(RunCli("relight " + d + "/transfer.vdb -o " + d + "/c.vdb", log), 2);
  EXPECT_EQ(RunCli("relight " + d + "/transfer.vdb --uniform 1,1 -o " + d + "/c.vdb", log), 2);
  EXPECT_EQ(RunCli("relight " + d + "/transfer.vdb --environment " + d + "/missing.exr -o " + d +
                       "/c.vdb",
                   log),
            2);
  Write(d + "/bad.json", R"({"coefficients": [[1, 2, 3], [4, 5, 6]]})");
  EXPECT_EQ(
      RunCli("relight " + d + "/transfer.vdb --environment " + d + "/bad.json -o " + d + "/c.vdb",
             log),
      2);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace probebake
