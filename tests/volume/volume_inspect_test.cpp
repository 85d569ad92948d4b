// `probebake inspect`: the report's counts, grids and per-grid statistics against values computed
// here from the volume's own arrays, and the text and JSON forms.
#include "probebake/volume/volume_inspect.h"

#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <utility>
#include <vector>

#include "probebake/volume/vdb_io.h"
#include "volume/test_volumes.h"

namespace probebake {
namespace {

using testing::MakeTestMetadata;
using testing::MakeTestVolume;
using testing::TempDir;
using testing::TestVolumeSpec;

struct Expected {
  double min[3], max[3], mean[3];
};

// Min, max and mean per channel over the active probes, computed independently of the reader.
Expected Stats(const ProbeVolume& v, const std::vector<float>& values, int channels) {
  Expected e;
  double sum[3] = {0, 0, 0};
  for (int ch = 0; ch < channels; ++ch) {
    e.min[ch] = std::numeric_limits<double>::infinity();
    e.max[ch] = -std::numeric_limits<double>::infinity();
  }
  int64_t n = 0;
  for (size_t p = 0; p < v.active.size(); ++p) {
    if (!v.active[p]) continue;
    ++n;
    for (int ch = 0; ch < channels; ++ch) {
      const double x = values[size_t(channels) * p + size_t(ch)];
      e.min[ch] = std::min(e.min[ch], x);
      e.max[ch] = std::max(e.max[ch], x);
      sum[ch] += x;
    }
  }
  for (int ch = 0; ch < channels; ++ch) e.mean[ch] = sum[ch] / double(n);
  return e;
}

constexpr const char* kPython = "/usr/bin/python3";

// Runs `script` with Debian's Python and `args` (each shell-quoted with '...'); returns its exit
// status and output (stdout and stderr).
std::pair<int, std::string> RunPython(const TempDir& dir, const std::string& script,
                                      const std::vector<std::string>& args) {
  const std::string scriptPath = dir.File("check.py");
  std::ofstream(scriptPath) << script;
  std::string command = std::string(kPython) + " '" + scriptPath + "'";
  for (const std::string& arg : args) command += " '" + arg + "'";
  command += " 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return {-1, "popen failed"};
  std::string output;
  char buffer[1024];
  size_t got;
  while ((got = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) output.append(buffer, got);
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

class Inspect : public ::testing::Test {
 protected:
  void SetUp() override {
    TestVolumeSpec spec;
    spec.irradiance = true;
    spec.awkwardValues = false;  // FLT_MAX would swamp the means
    volume_ = MakeTestVolume(spec);
    path_ = dir_.File("volume.vdb");
    PB_ASSERT_OK(WriteProbeVolume(path_, volume_, MakeTestMetadata()));
    for (uint8_t a : volume_.active) active_ += a;
    for (size_t p = 0; p < volume_.active.size(); ++p) {
      invalid_ += volume_.active[p] && volume_.validity[p] == 0;
    }
    ASSERT_GT(invalid_, 0);
  }

  ProbeVolume volume_;
  TempDir dir_;
  std::string path_;
  int64_t active_ = 0, invalid_ = 0;
};

TEST_F(Inspect, CountsGridsAndStatistics) {
  const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path_);
  ASSERT_TRUE(report.ok()) << report.status();
  EXPECT_EQ(report->probes, active_);
  EXPECT_EQ(report->invalidProbes, invalid_);
  EXPECT_GT(report->fileBytes, 0);
  ASSERT_EQ(report->grids.size(), size_t(2 * volume_.CoeffCount() + 4));

  for (const GridReport& g : report->grids) {
    SCOPED_TRACE(g.name);
    EXPECT_EQ(g.activeVoxels, active_);
    const std::vector<float>* values = nullptr;
    int channels = 1;
    if (g.name.find("_sh_") != std::string::npos) {
      const size_t c = size_t(std::stoi(g.name.substr(g.name.size() - 2)));
      values = g.name[0] == 'r' ? &volume_.radiance[c] : &volume_.irradiance[c];
      channels = 3;
      EXPECT_EQ(g.valueType, "vec3s");
    } else {
      values = g.name == "validity"       ? &volume_.validity
               : g.name == "std_error"    ? &volume_.stdError
               : g.name == "std_error_l0" ? &volume_.stdErrorL0
                                          : &volume_.sampleCount;
      EXPECT_EQ(g.valueType, "float");
    }
    ASSERT_EQ(g.channels, channels);
    const Expected e = Stats(volume_, *values, channels);
    for (int ch = 0; ch < channels; ++ch) {
      // Min and max are stored floats, exact in double. The means are sums of the same ~50
      // doubles in another order: each partial sum rounds by at most 2^-53 of its magnitude,
      // so |difference| <= n * 2^-53 * sum|x| / n < 1e-14 * max|x|.
      EXPECT_EQ(g.min[ch], e.min[ch]) << ch;
      EXPECT_EQ(g.max[ch], e.max[ch]) << ch;
      const double tolerance = 1e-14 * std::max(std::abs(e.min[ch]), std::abs(e.max[ch]));
      EXPECT_NEAR(g.mean[ch], e.mean[ch], tolerance) << ch;
    }
    // Active box: the active probes' index range.
    int lo[3] = {INT32_MAX, INT32_MAX, INT32_MAX}, hi[3] = {-1, -1, -1};
    for (int64_t p = 0; p < volume_.grid.ProbeCount(); ++p) {
      if (!volume_.active[size_t(p)]) continue;
      int ijk[3];
      volume_.grid.Coords(p, &ijk[0], &ijk[1], &ijk[2]);
      for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], ijk[a]), hi[a] = std::max(hi[a], ijk[a]);
    }
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(g.bboxMin[a], lo[a]);
      EXPECT_EQ(g.bboxMax[a], hi[a]);
    }
  }
  const auto it = std::find_if(report->metadata.begin(), report->metadata.end(),
                               [](const MetadataEntry& m) { return m.name == "sh_order"; });
  ASSERT_NE(it, report->metadata.end());
  EXPECT_EQ(it->type, "int32");
  EXPECT_EQ(it->value, "2");
}

TEST_F(Inspect, KnownValuesGiveKnownStatistics) {
  // Radiance coefficient 0 = (p, 2p, -p) at probe p (p = linear index), validity 1 except 2 probes.
  TestVolumeSpec spec;
  spec.inactiveEvery = 4;  // probes 3, 7, 11, ... inactive
  ProbeVolume v = MakeTestVolume(spec);
  double sum = 0;
  int64_t n = 0;
  double lo = 1e300, hi = -1e300;
  for (size_t p = 0; p < v.active.size(); ++p) {
    v.validity[p] = v.active[p] ? 1.0f : 0.0f;
    v.radiance[0][3 * p] = v.active[p] ? float(p) : 0.0f;
    v.radiance[0][3 * p + 1] = v.active[p] ? 2.0f * float(p) : 0.0f;
    v.radiance[0][3 * p + 2] = v.active[p] ? -float(p) : 0.0f;
    if (v.active[p])
      sum += double(p), ++n, lo = std::min(lo, double(p)), hi = std::max(hi, double(p));
  }
  v.validity[0] = v.validity[1] = 0;
  const std::string path = dir_.File("known.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, v, MakeTestMetadata()));
  const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path);
  ASSERT_TRUE(report.ok()) << report.status();
  // 60 probes, every 4th from 3 inactive: 45 active; indices 0..59 minus 3, 7, ..., 59.
  EXPECT_EQ(n, 45);
  EXPECT_EQ(report->probes, 45);
  EXPECT_EQ(report->invalidProbes, 2);
  const GridReport& r0 =
      *std::find_if(report->grids.begin(), report->grids.end(),
                    [](const GridReport& g) { return g.name == "radiance_sh_00"; });
  // Sum of 0..59 is 1770; minus 3 + 7 + ... + 59 = 15 terms averaging 31 = 465: 1305 / 45 = 29.
  EXPECT_EQ(sum, 1305);
  EXPECT_EQ(r0.mean[0], 29);
  EXPECT_EQ(r0.mean[1], 58);
  EXPECT_EQ(r0.mean[2], -29);
  EXPECT_EQ(r0.min[0], 0);
  EXPECT_EQ(r0.max[0], 58);
  EXPECT_EQ(r0.min[1], 0);
  EXPECT_EQ(r0.max[1], 116);
  EXPECT_EQ(r0.min[2], -58);
  EXPECT_EQ(r0.max[2], 0);
  EXPECT_EQ(lo, 0);
  EXPECT_EQ(hi, 58);
  const GridReport& validity =
      *std::find_if(report->grids.begin(), report->grids.end(),
                    [](const GridReport& g) { return g.name == "validity"; });
  EXPECT_EQ(validity.min[0], 0);
  EXPECT_EQ(validity.max[0], 1);
  EXPECT_EQ(validity.mean[0], 43.0 / 45.0);
}

TEST_F(Inspect, NonFiniteValuesAreCountedAndLeftOutOfTheStatistics) {
  // Radiance coefficient 0 = (p, p, p) at probe p, every probe active; probe 0 gets a NaN in one
  // channel and probe 1 an infinity: both voxels are counted and left out of every channel.
  TestVolumeSpec spec;
  spec.inactiveEvery = 0;
  ProbeVolume v = MakeTestVolume(spec);
  const size_t probes = v.active.size();
  for (size_t p = 0; p < probes; ++p)
    for (int ch = 0; ch < 3; ++ch) v.radiance[0][3 * p + size_t(ch)] = float(p);
  v.radiance[0][1] = std::numeric_limits<float>::quiet_NaN();
  v.radiance[0][3 + 2] = std::numeric_limits<float>::infinity();
  v.stdError[4] = -std::numeric_limits<float>::infinity();
  const std::string path = dir_.File("nonfinite.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, v, MakeTestMetadata()));
  const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path);
  ASSERT_TRUE(report.ok()) << report.status();
  auto grid = [&](const std::string& name) {
    return *std::find_if(report->grids.begin(), report->grids.end(),
                         [&](const GridReport& g) { return g.name == name; });
  };
  const GridReport r0 = grid("radiance_sh_00");
  EXPECT_EQ(r0.nonFinite, 2);
  // Probes 2 .. n-1: mean (n + 1) / 2, exact in double for these few small integers.
  const double n = double(probes);
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_EQ(r0.min[ch], 2) << ch;
    EXPECT_EQ(r0.max[ch], n - 1) << ch;
    EXPECT_EQ(r0.mean[ch], (n + 1) / 2) << ch;
  }
  EXPECT_EQ(grid("std_error").nonFinite, 1);
  EXPECT_TRUE(std::isfinite(grid("std_error").mean[0]));
  EXPECT_EQ(grid("radiance_sh_01").nonFinite, 0);
  const std::string text = FormatVolumeReport(*report);
  EXPECT_NE(text.find("NON-FINITE 2"), std::string::npos) << text;
  EXPECT_NE(text.find("NON-FINITE 1"), std::string::npos) << text;
  const std::string json = VolumeReportJson(*report);
  EXPECT_NE(json.find("\"nonFinite\":2"), std::string::npos) << json;
}

TEST_F(Inspect, TextNamesProbesAndEveryGrid) {
  const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path_);
  ASSERT_TRUE(report.ok()) << report.status();
  const std::string text = FormatVolumeReport(*report);
  EXPECT_NE(text.find("probes: " + std::to_string(active_) +
                      " (invalid: " + std::to_string(invalid_) + ")"),
            std::string::npos)
      << text;
  for (int c = 0; c < volume_.CoeffCount(); ++c) {
    EXPECT_NE(text.find(RadianceGridName(c)), std::string::npos) << text;
    EXPECT_NE(text.find(IrradianceGridName(c)), std::string::npos) << text;
  }
  for (const char* name : {"validity", "std_error", "sample_count", "sh_basis", "stats"}) {
    EXPECT_NE(text.find(name), std::string::npos) << name << "\n" << text;
  }
}

TEST_F(Inspect, JsonParsesWithPythonAndHoldsTheFigures) {
  if (::access(kPython, X_OK) != 0) GTEST_SKIP() << kPython << " is missing";
  const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path_);
  ASSERT_TRUE(report.ok()) << report.status();
  const std::string jsonPath = dir_.File("report.json");
  std::ofstream(jsonPath) << VolumeReportJson(*report);
  const std::string check =
      "import json,sys\n"
      "d=json.load(open(sys.argv[1]))\n"
      "assert d['probes']==int(sys.argv[2]), d['probes']\n"
      "assert d['invalidProbes']==int(sys.argv[3]), d['invalidProbes']\n"
      "assert d['metadata']['sh_order']==2\n"
      "assert d['metadata']['has_irradiance'] is True\n"
      "assert d['metadata']['stats']['probes']==int(sys.argv[2]), d['metadata']['stats']\n"
      "assert d['metadata']['grid_counts']==[3,4,5]\n"
      "names=[g['name'] for g in d['grids']]\n"
      "assert len(names)==22 and 'radiance_sh_08' in names and 'validity' in names, names\n"
      "g=[g for g in d['grids'] if g['name']=='validity'][0]\n"
      "assert len(g['mean'])==1 and g['activeVoxels']==int(sys.argv[2]), g\n"
      "print('ok')\n";
  const auto [status, output] =
      RunPython(dir_, check, {jsonPath, std::to_string(active_), std::to_string(invalid_)});
  EXPECT_EQ(status, 0) << output;
  EXPECT_EQ(output, "ok\n");
}

// The report is JSON even when the file's path and metadata strings are not UTF-8 (such bytes
// become U+FFFD), string metadata holding JSON is embedded as JSON, and int64 metadata beyond 2^53
// (not exact as a JSON number) is a string of its exact digits.
TEST_F(Inspect, JsonIsValidForAnyBytesAndExactForLargeIntegers) {
  if (::access(kPython, X_OK) != 0) GTEST_SKIP() << kPython << " is missing";
  VolumeMetadata meta = MakeTestMetadata();
  meta.sceneDigest = "digest \xff\xfe end";
  meta.settingsJson = "{\"note\":\"caf\xe9\",\"list\":[1,2.5,null,true],\"n\":{}}";
  meta.seed = 0x9E3779B97F4A7C15ull;                  // int64 -7046029254386353131, beyond 2^53
  const std::string path = dir_.File("caf\xe9.vdb");  // Latin-1, not UTF-8
  PB_ASSERT_OK(WriteProbeVolume(path, volume_, meta));
  const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path);
  ASSERT_TRUE(report.ok()) << report.status();
  const std::string jsonPath = dir_.File("report.json");
  std::ofstream(jsonPath) << VolumeReportJson(*report);
  const std::string check =
      "import json,sys\n"
      "d=json.load(open(sys.argv[1], encoding='utf-8', errors='strict'))\n"
      "assert d['path'].endswith('/caf\\ufffd.vdb'), d['path']\n"
      "m=d['metadata']\n"
      "assert m['scene_digest']=='digest \\ufffd\\ufffd end', m['scene_digest']\n"
      "assert m['settings']=={'note':'caf\\ufffd','list':[1,2.5,None,True],'n':{}}, "
      "m['settings']\n"
      "assert m['seed']=='-7046029254386353131', m['seed']\n"
      "assert m['samples_per_probe']==8589934592, m['samples_per_probe']\n"
      "assert m['grid_spacing']==[0.5,1.25,2.0], m['grid_spacing']\n"
      "assert m['grid_surface_distance']==0.375, m['grid_surface_distance']\n"
      "print('ok')\n";
  const auto [status, output] = RunPython(dir_, check, {jsonPath});
  EXPECT_EQ(status, 0) << output;
  EXPECT_EQ(output, "ok\n");
}

// Stable text: the same report always prints the same JSON, keys in ascending order.
TEST_F(Inspect, JsonIsStableWithSortedKeys) {
  const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path_);
  ASSERT_TRUE(report.ok()) << report.status();
  const std::string json = VolumeReportJson(*report);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(VolumeReportJson(*report), json);
  // Top-level keys in ascending order: fileBytes, grids, invalidProbes, metadata, path, probes.
  const std::string head = "{\"fileBytes\":" + std::to_string(report->fileBytes) + ",\"grids\":[";
  const std::string middle =
      "],\"invalidProbes\":" + std::to_string(report->invalidProbes) + ",\"metadata\":{";
  const std::string tail =
      ",\"path\":\"" + path_ + "\",\"probes\":" + std::to_string(report->probes) + "}";
  EXPECT_EQ(json.rfind(head, 0), 0u) << json;
  EXPECT_NE(json.find(middle), std::string::npos) << json;
  ASSERT_GE(json.size(), tail.size());
  EXPECT_EQ(json.substr(json.size() - tail.size()), tail) << json;
  // And inside: a grid's keys, the metadata's keys.
  EXPECT_NE(json.find("{\"activeVoxels\":" + std::to_string(active_) + ",\"bboxMax\":["),
            std::string::npos)
      << json;
  EXPECT_NE(json.find("\"metadata\":{\"color_space\":\"linear-rec709\",\"generator\":"),
            std::string::npos)
      << json;
}

TEST_F(Inspect, VolumeWithoutBakedProbes) {
  TestVolumeSpec spec;
  spec.inactiveEvery = 1;  // every probe inactive
  const std::string path = dir_.File("empty.vdb");
  PB_ASSERT_OK(WriteProbeVolume(path, MakeTestVolume(spec), MakeTestMetadata()));
  const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path);
  ASSERT_TRUE(report.ok()) << report.status();
  EXPECT_EQ(report->probes, 0);
  EXPECT_EQ(report->invalidProbes, 0);
  ASSERT_EQ(report->grids.size(), 13u);
  for (const GridReport& g : report->grids) {
    EXPECT_EQ(g.activeVoxels, 0) << g.name;
    EXPECT_EQ(g.mean[0], 0) << g.name;
  }
  const std::string text = FormatVolumeReport(*report);
  EXPECT_NE(text.find("probes: 0 (invalid: 0)"), std::string::npos) << text;
  EXPECT_NE(text.find("bbox empty"), std::string::npos) << text;
  EXPECT_NE(VolumeReportJson(*report).find("\"bboxMin\":null"), std::string::npos);
}

TEST_F(Inspect, TextShowsASeedPast2To63AsTheSeed) {
  for (const uint64_t seed : {uint64_t{7}, ~uint64_t{0}, uint64_t{1} << 63}) {
    VolumeMetadata meta = MakeTestMetadata();
    meta.seed = seed;
    const std::string path = dir_.File("seed.vdb");
    PB_ASSERT_OK(WriteProbeVolume(path, MakeTestVolume(TestVolumeSpec()), meta));
    const absl::StatusOr<VolumeReport> report = InspectProbeVolume(path);
    ASSERT_TRUE(report.ok()) << report.status();
    const std::string text = FormatVolumeReport(*report);
    const std::string line = "seed (int64): " + std::to_string(int64_t(seed)) +
                             (int64_t(seed) < 0 ? " (seed " + std::to_string(seed) + ")" : "") +
                             "\n";
    EXPECT_NE(text.find(line), std::string::npos) << text;
  }
}

TEST_F(Inspect, MissingFileIsNotFound) {
  const absl::StatusOr<VolumeReport> report = InspectProbeVolume(dir_.File("absent.vdb"));
  EXPECT_EQ(report.status().code(), absl::StatusCode::kNotFound) << report.status();
}

}  // namespace
}  // namespace probebake
