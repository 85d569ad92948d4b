// Small helpers of the accuracy and speed benchmark: clocks (wall, process CPU, thread CPU), the
// machine's load, resident memory from /proc/self/status, and file I/O.
#pragma once

#include <sched.h>

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace probebake::bench {

// Monotonic wall clock, seconds since an arbitrary epoch.
double WallSeconds();
// CPU time (user + system) of the whole process, every thread, seconds.
double ProcessCpuSeconds();
// CPU time of the calling thread, seconds.
double ThreadCpuSeconds();
// The 1-minute load average (/proc/loadavg); -1 if unreadable.
double LoadAverage1();
// Hardware threads of the machine.
int HardwareThreads();

// Pins the calling thread to the CPU it is running on for the object's lifetime, then restores
// the thread's affinity; does nothing where the affinity cannot be read or set. Both halves of a
// paired reading then run on one CPU: the vCPUs of a shared VM differ in speed from one minute to
// the next (a tracer bake on one and raw Embree on the other were seen to read 1.4x apart, their
// roles swapping from one pair to the next).
class CpuPin {
 public:
  CpuPin();
  ~CpuPin();
  CpuPin(const CpuPin&) = delete;
  CpuPin& operator=(const CpuPin&) = delete;

  // The CPU the thread is pinned to; -1 when pinning failed (the thread may then migrate).
  int cpu() const { return cpu_; }

 private:
  cpu_set_t saved_;
  int cpu_ = -1;
};

// Resident memory figures of this process from /proc/self/status, bytes; -1 if unavailable.
int64_t PeakRssBytes();     // VmHWM
int64_t CurrentRssBytes();  // VmRSS
// Resets VmHWM to the current RSS (writes "5" to /proc/self/clear_refs). False if not permitted.
bool ResetPeakRss();

// The median of `values` (non-empty).
double Median(std::vector<double> values);

absl::StatusOr<std::string> ReadFileBytes(const std::string& path);
// Writes `bytes` to `path` through a temporary file and a rename, so a reader never sees a
// partial file. Creates the parent folder.
absl::Status WriteFileAtomic(const std::string& path, const std::string& bytes);

// printf-style formatting into a std::string.
std::string Format(const char* format, ...) __attribute__((format(printf, 1, 2)));

}  // namespace probebake::bench
