// pyopenvdb (which knows FloatGrid, BoolGrid and Vec3SGrid only) reads the probe volume file:
// grid names and classes, voxel values, the transform and the metadata with their Python types.
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>

#include "probebake/base/version.h"
#include "probebake/volume/vdb_io.h"
#include "volume/test_volumes.h"

namespace probebake {
namespace {

using testing::MakeTestMetadata;
using testing::MakeTestVolume;
using testing::TempDir;
using testing::TestVolumeSpec;

constexpr const char* kPython = "/usr/bin/python3";

// Runs `command` through the shell; returns its exit status and appends its output to *output.
int RunCommand(const std::string& command, std::string* output) {
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return -1;
  char buffer[4096];
  size_t n;
  while ((n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) output->append(buffer, n);
  const int status = ::pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string Float(float x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.9g", double(x));
  return buffer;
}

std::string Double(double x) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", x);
  return buffer;
}

std::string Quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out.push_back('\\');
    out.push_back(c);
  }
  return out + "\"";
}

TEST(PyOpenVdb, ReadsGridsValuesTransformAndMetadata) {
  if (::access(kPython, X_OK) != 0) GTEST_SKIP() << kPython << " is missing";
  std::string probe;
  if (RunCommand(std::string(kPython) + " -c 'import pyopenvdb'", &probe) != 0) {
    GTEST_SKIP() << "pyopenvdb is not importable by " << kPython << ": " << probe;
  }

  TestVolumeSpec spec;
  spec.irradiance = true;
  const ProbeVolume volume = MakeTestVolume(spec);
  const VolumeMetadata meta = MakeTestMetadata();
  TempDir dir;
  const std::string path = dir.File("volume.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, volume, meta));

  const ProbeGrid& g = volume.grid;
  int64_t active = 0;
  for (uint8_t a : volume.active) active += a;

  std::string json = "{\"grids\":{";
  for (int c = 0; c < volume.CoeffCount(); ++c) {
    json += Quote(RadianceGridName(c)) + ":\"Vec3SGrid\"," + Quote(IrradianceGridName(c)) +
            ":\"Vec3SGrid\",";
  }
  json +=
      "\"validity\":\"FloatGrid\",\"std_error\":\"FloatGrid\",\"std_error_l0\":\"FloatGrid\","
      "\"sample_count\":\"FloatGrid\"}";
  json += std::string(",\"activeVoxels\":") + std::to_string(active) + ",\"voxels\":[";
  // A few active probes, including the first ones that hold the awkward values.
  int listed = 0;
  for (int64_t p = 0; p < g.ProbeCount() && listed < 6; p += (listed < 3 ? 1 : 11)) {
    if (!volume.active[size_t(p)]) continue;
    int i, j, k;
    g.Coords(p, &i, &j, &k);
    const std::string ijk =
        std::to_string(i) + "," + std::to_string(j) + "," + std::to_string(k) + ",";
    for (int c : {0, 3, volume.CoeffCount() - 1}) {
      const float* r = &volume.radiance[size_t(c)][3 * size_t(p)];
      const float* e = &volume.irradiance[size_t(c)][3 * size_t(p)];
      json += std::string("[") + Quote(RadianceGridName(c)) + "," + ijk + "[" + Float(r[0]) + "," +
              Float(r[1]) + "," + Float(r[2]) + "]],";
      json += std::string("[") + Quote(IrradianceGridName(c)) + "," + ijk + "[" + Float(e[0]) +
              "," + Float(e[1]) + "," + Float(e[2]) + "]],";
    }
    json += std::string("[\"validity\",") + ijk + "[" + Float(volume.validity[size_t(p)]) + "]],";
    json += std::string("[\"std_error\",") + ijk + "[" + Float(volume.stdError[size_t(p)]) + "]],";
    json +=
        std::string("[\"std_error_l0\",") + ijk + "[" + Float(volume.stdErrorL0[size_t(p)]) + "]],";
    json += std::string("[\"sample_count\",") + ijk + "[" + Float(volume.sampleCount[size_t(p)]) +
            "]],";
    ++listed;
  }
  ASSERT_GE(listed, 4);
  json.pop_back();  // trailing comma
  json += "],\"world\":[";
  for (const auto& ijk :
       {std::array<int, 3>{0, 0, 0}, std::array<int, 3>{2, 3, 4}, std::array<int, 3>{1, 2, 3}}) {
    const Vec3d p = g.Position(ijk[0], ijk[1], ijk[2]);
    json += std::string("[") + std::to_string(ijk[0]) + "," + std::to_string(ijk[1]) + "," +
            std::to_string(ijk[2]) + ",[" + Double(p.x) + "," + Double(p.y) + "," + Double(p.z) +
            "]],";
  }
  json.pop_back();
  json += "],\"metadata\":{";
  json += "\"probebake_format\":[\"int\",4],\"sh_order\":[\"int\",2],";
  json += "\"sh_basis\":[\"str\",\"real-orthonormal-condon-shortley-zpolar\"],";
  json += "\"sh_window\":[\"str\",\"HANNING\"],\"quantity\":[\"str\",\"radiance\"],";
  json += "\"has_irradiance\":[\"bool\",true],\"color_space\":[\"str\",\"linear-rec709\"],";
  json +=
      std::string("\"samples_per_probe\":[\"int\",") + std::to_string(meta.samplesPerProbe) + "],";
  json += std::string("\"max_depth\":[\"int\",") + std::to_string(meta.maxDepth) + "],";
  json += std::string("\"seed\":[\"int\",") + std::to_string(int64_t(meta.seed)) + "],";
  json += std::string("\"scene_digest\":[\"str\",") + Quote(meta.sceneDigest) + "],";
  json += std::string("\"settings\":[\"str\",") + Quote(meta.settingsJson) + "],";
  json += std::string("\"generator\":[\"str\",") +
          Quote(std::string(kGeneratorName) + " " + kVersion) + "],";
  json += "\"grid_counts\":[\"vec3i\",[3,4,5]],";
  json += "\"grid_min\":[\"vec3d\",[-3.5,-1,-10.25]],";
  json += "\"grid_spacing\":[\"vec3d\",[0.5,1.25,2]],";
  json += "\"grid_placement\":[\"str\",\"NEAR_SURFACES\"],";
  json += "\"grid_surface_distance\":[\"float\",0.375]}}";
  const std::string expectations = dir.File("expect.json");
  std::ofstream(expectations) << json;

  const std::string script = std::string(PROBEBAKE_SOURCE_DIR) + "/tests/volume/read_volume.py";
  std::string output;
  const int exitCode = RunCommand(
      std::string(kPython) + " '" + script + "' '" + path + "' '" + expectations + "'", &output);
  EXPECT_EQ(exitCode, 0) << output;
  EXPECT_NE(output.find(", 0 failures"), std::string::npos) << output;
}

}  // namespace
}  // namespace probebake
