#include "volume/test_volumes.h"

#include <unistd.h>

#include <algorithm>
#include <cfloat>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <stdexcept>

namespace probebake::testing {
namespace {

// SplitMix64: a stateless hash of (seed, counter) to 64 bits.
uint64_t Hash(uint64_t seed, uint64_t n) {
  uint64_t z = seed * 0x9E3779B97F4A7C15ull + n + 0x632BE59BD9B4E019ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// A float in [-4, 4) from the hash, with all 24 mantissa bits in use.
float HashFloat(uint64_t seed, uint64_t n) {
  return float(int32_t(Hash(seed, n) >> 40) - (1 << 23)) * (4.0f / float(1 << 23));
}

}  // namespace

ProbeVolume MakeTestVolume(const TestVolumeSpec& spec) {
  ProbeVolume v;
  v.grid.origin = spec.origin;
  v.grid.spacing = spec.spacing;
  for (int a = 0; a < 3; ++a) v.grid.counts[a] = spec.counts[a];
  v.grid.placement = Placement::kNearSurfaces;
  v.grid.surfaceDistance = 0.375;
  v.shOrder = spec.shOrder;
  const size_t n = size_t(v.grid.ProbeCount());
  v.active.assign(n, 1);
  v.validity.assign(n, 1.0f);
  v.stdError.assign(n, 0.0f);
  v.stdErrorL0.assign(n, 0.0f);
  v.sampleCount.assign(n, 0.0f);
  int64_t activeCount = 0, invalidCount = 0;
  for (size_t p = 0; p < n; ++p) {
    if (spec.inactiveEvery > 0 &&
        p % size_t(spec.inactiveEvery) == 3 % size_t(spec.inactiveEvery)) {
      v.active[p] = 0;
    }
    if (!v.active[p]) {
      v.validity[p] = 0;
      continue;
    }
    ++activeCount;
    if (spec.invalidEvery > 0 && activeCount % spec.invalidEvery == 0) {
      v.validity[p] = 0;
      ++invalidCount;
    }
    v.stdError[p] = std::abs(HashFloat(spec.seed + 1, p)) * 0.01f;
    v.stdErrorL0[p] = std::abs(HashFloat(spec.seed + 2, p)) * 0.01f;
    v.sampleCount[p] = float(256 + (Hash(spec.seed + 2, p) % 1024));
  }
  const int coefficients = v.CoeffCount();
  auto fill = [&](std::vector<std::vector<float>>* planes, uint64_t salt) {
    planes->assign(size_t(coefficients), std::vector<float>(3 * n, 0.0f));
    for (int c = 0; c < coefficients; ++c) {
      std::vector<float>& plane = (*planes)[size_t(c)];
      for (size_t p = 0; p < n; ++p) {
        if (!v.active[p]) continue;
        for (size_t ch = 0; ch < 3; ++ch) {
          plane[3 * p + ch] = HashFloat(spec.seed * 1000 + salt + uint64_t(c), 3 * p + ch);
        }
      }
    }
    if (!spec.awkwardValues) return;
    // Awkward values at the first active probes of plane 0 and the last plane.
    const float awkward[] = {-0.0f, 1e-40f, FLT_MAX, -FLT_MIN, 1.0f / 3.0f, -7.5e-23f};
    size_t k = 0;
    for (size_t p = 0; p < n && k < std::size(awkward); ++p) {
      if (!v.active[p]) continue;
      (*planes)[0][3 * p + k % 3] = awkward[k];
      planes->back()[3 * p + (k + 1) % 3] = awkward[k];
      ++k;
    }
  };
  fill(&v.radiance, 17);
  if (spec.irradiance) fill(&v.irradiance, 4242);
  v.window = "HANNING";
  v.stats.wallSeconds = 12.345678901234567;
  v.stats.threads = 2;
  v.stats.probes = activeCount;
  v.stats.samples = activeCount * 512 + 3;
  v.stats.rays = int64_t(1) << 40;
  v.stats.invalidProbes = invalidCount;
  return v;
}

void PrintTo(const AwkwardGrid& grid, std::ostream* os) {
  *os << std::setprecision(17) << grid.name << ": origin (" << grid.origin.x << ", "
      << grid.origin.y << ", " << grid.origin.z << "), spacing (" << grid.spacing.x << ", "
      << grid.spacing.y << ", " << grid.spacing.z << "), counts " << grid.counts[0] << "x"
      << grid.counts[1] << "x" << grid.counts[2];
}

std::vector<AwkwardGrid> AwkwardGrids() {
  const double third = 1.0 / 3.0;
  std::vector<AwkwardGrid> grids = {
      // The service engineer's case: min 0, max 2, 4 probes per axis.
      {"TwoThirds", {0, 0, 0}, {(2.0 - 0.0) / 3, (2.0 - 0.0) / 3, (2.0 - 0.0) / 3}, {4, 4, 4}},
      // The same spacing from min -1, max 1: (s + t) - t no longer gives s back.
      {"TwoThirdsFromMinusOne", {-1, -1, -1}, {2.0 / 3, 2.0 / 3, 2.0 / 3}, {4, 4, 4}},
      {"OneThird", {0, 0, 0}, {third, third, third}, {4, 3, 2}},
      {"Tenth", {-0.3, 0.7, 0.1}, {0.1, 0.1, 0.1}, {5, 4, 3}},
      {"Milli", {0.001, -0.002, 0.003}, {1e-3, 1e-3, 1e-3}, {5, 4, 3}},
      {"TenThousandThirds", {-1e4, 0, 1e4}, {1e4 / 3, 1e4 / 3, 1e4 / 3}, {4, 3, 2}},
      {"PerAxis", {0.25, -1.5, 3.0}, {third, 0.1, 1e4 / 3}, {4, 5, 3}},
      {"FarOriginTwoThirds", {1e5, -1e5, 1e5}, {2.0 / 3, 2.0 / 3, 2.0 / 3}, {4, 4, 4}},
      {"FarOriginMilli", {1e5 + 0.1, -1e5 - 0.1, 1e5 / 3}, {1e-3, 0.1, third}, {5, 4, 3}},
  };
  // The baker's spacing: (max - min) / (n - 1) per axis, with different n per axis.
  const double minima[] = {0.0, -1.7, 12345.678, 1e5};
  const double extents[] = {1.0, 2.0, 0.3, 7.0, 1e4};
  const int counts[] = {3, 4, 6, 7, 10};
  int index = 0;
  for (const double lo : minima) {
    for (const double extent : extents) {
      for (const int n : counts) {
        const int ny = 2 + n % 4, nz = 2 + (n + 1) % 3;
        const double hi = lo + extent;
        grids.push_back({"Sweep" + std::to_string(index++),
                         {lo, -lo, lo * 0.5},
                         {(hi - lo) / (n - 1), (hi - lo) / (ny - 1), (hi - lo) / (nz - 1)},
                         {n, ny, nz}});
      }
    }
  }
  return grids;
}

VolumeMetadata MakeTestMetadata() {
  VolumeMetadata m;
  m.samplesPerProbe = int64_t(1) << 33;
  m.maxDepth = 8;
  m.seed = ~uint64_t(0) - 4;  // 2^64 - 5: above int64's range
  m.sceneDigest = "9f86d081884c7d659a2feaa0c55ad015a3bf4f1b2b0b822cd15d6c15b0f00a08";
  m.settingsJson =
      "{\"shOrder\":2,\"samplesPerProbe\":1024,\"window\":\"NONE\",\"note\":\"quote \\\" "
      "caf\xc3\xa9\"}";
  return m;
}

namespace {
int64_t StatusField(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string prefix = std::string(field) + ":";
  while (std::getline(in, line)) {
    if (line.rfind(prefix, 0) == 0) return int64_t(std::stoll(line.substr(prefix.size()))) * 1024;
  }
  return -1;
}
}  // namespace

int64_t CurrentRssBytes() {
  return StatusField("VmRSS");
}
int64_t PeakRssBytes() {
  return StatusField("VmHWM");
}

bool ResetPeakRss() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return bool(out);
}

TempDir::TempDir() {
  const char* base = std::getenv("TEST_TMPDIR");
  if (base == nullptr || *base == '\0') base = std::getenv("TMPDIR");
  if (base == nullptr || *base == '\0') base = "/tmp";
  std::string templ = std::string(base) + "/probebake_volume_XXXXXX";
  if (::mkdtemp(templ.data()) == nullptr) throw std::runtime_error("mkdtemp failed: " + templ);
  path_ = templ;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::vector<std::string> TempDir::List() const {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(path_)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

}  // namespace probebake::testing
