// Synthetic probe volumes and temp-dir helpers for the volume tests and benchmark.
#pragma once

#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

#include "probebake/bake/probe_volume.h"

// ASSERT_TRUE(status.ok()) that prints the status on failure (for gtest files).
#define PB_ASSERT_OK(expr)                      \
  do {                                          \
    const ::absl::Status pb_status_ = (expr);   \
    ASSERT_TRUE(pb_status_.ok()) << pb_status_; \
  } while (false)

namespace probebake::testing {

struct TestVolumeSpec {
  int counts[3] = {3, 4, 5};
  Vec3d origin{-3.5, -1.0, -10.25};
  Vec3d spacing{0.5, 1.25, 2.0};
  int shOrder = 2;
  bool irradiance = false;
  // Probes p with p % inactiveEvery == 3 % inactiveEvery are inactive (1: all of them; 0: none);
  // every invalidEvery-th active probe is invalid (0: none).
  int inactiveEvery = 7;
  int invalidEvery = 5;
  uint64_t seed = 1;
  // Put awkward floats (-0, subnormal, FLT_MAX, tiny negative) into the first planes.
  bool awkwardValues = true;
};

// Deterministic pseudo-random contents; inactive probes hold 0 in every plane (files do not
// store them, so a read gives 0 there). Stats and window are filled too.
ProbeVolume MakeTestVolume(const TestVolumeSpec& spec);

// A grid whose origin and spacing are awkward in binary floating point: spacings such as 2/3 that
// the baker computes as (max - min) / (n - 1), per-axis different spacings, origins far from 0.
struct AwkwardGrid {
  std::string name;  // a valid gtest parameter name
  Vec3d origin;
  Vec3d spacing;
  int counts[3];
};
// Prints the name, origin, spacing and counts (gtest's default prints raw bytes).
void PrintTo(const AwkwardGrid& grid, std::ostream* os);
// A fixed list of named cases followed by a sweep of (max - min) / (n - 1) spacings over several
// minima, extents and counts.
std::vector<AwkwardGrid> AwkwardGrids();

// Metadata with every field non-trivial (seed above 2^63, JSON with quotes and non-ASCII).
VolumeMetadata MakeTestMetadata();

// Resident memory of this process from /proc/self/status: VmRSS now and VmHWM, its peak since the
// last ResetPeakRss(). -1 when unavailable.
int64_t CurrentRssBytes();
int64_t PeakRssBytes();
// Resets the peak to the current RSS (writes 5 to /proc/self/clear_refs, Linux >= 4.0); false
// when that is not permitted.
bool ResetPeakRss();

// A fresh empty directory under ::testing::TempDir() (or $TMPDIR), removed with its contents by
// the destructor.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }
  std::string File(const std::string& name) const { return path_ + "/" + name; }
  // Names of the entries in the directory, sorted.
  std::vector<std::string> List() const;

 private:
  std::string path_;
};

}  // namespace probebake::testing
