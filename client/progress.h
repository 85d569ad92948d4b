// How the CLI shows a bake going on: a one-line progress bar redrawn in place on a terminal,
// a line per state change when stderr is not a terminal, or one JSON object per line on stdout
// with --json (for scripts).
#pragma once

#include <chrono>
#include <cstdio>
#include <string>
#include <string_view>

#include "probebake/bake/bake.h"
#include "probebake/v1/service.pb.h"

namespace probebake::client {

class ProgressView {
 public:
  enum class Mode { kBar, kLines, kJson };
  // kJson with `json`, else kBar when stderr is a terminal, else kLines.
  static Mode Choose(bool json);
  explicit ProgressView(Mode mode) : mode_(mode) {}
  ~ProgressView() { Done(); }

  Mode mode() const { return mode_; }
  // A state of a server job (WatchBakeJob message).
  void Update(const v1::BakeJob& job);
  // Notes a state already shown elsewhere (not shown again when the watch repeats it).
  void Seen(const v1::BakeJob& job) { lastState_ = int(job.state()); }
  // Progress of a local bake.
  void Update(const BakeProgress& progress);
  // Bytes of a download or upload.
  void Bytes(const std::string& label, int64_t done, int64_t total);
  // Ends the bar's line.
  void Done();

 private:
  void Bar(const std::string& label, int64_t done, int64_t total, double elapsedSeconds,
           int64_t resumed, double etaSeconds, double errorEstimate, int64_t errorUnknown);
  void Redraw(const std::string& line);

  Mode mode_;
  bool barOpen_ = false;
  int lastState_ = -1;
  std::string lastWaiting_;  // the job's progress.waiting last shown
  std::chrono::steady_clock::time_point lastDraw_{};
};

// "1:05" / "1:02:03" for a duration in seconds; "?" when negative.
std::string FormatDuration(double seconds);

// `text` as a JSON string literal, quotes included.
std::string JsonQuote(std::string_view text);

// The job as one line of JSON (proto3 JSON, lowerCamelCase).
std::string JobJson(const v1::BakeJob& job);

// A line for people: "bakeJobs/... SUCCEEDED 400/400 probes volume sha256:.../123".
std::string JobSummary(const v1::BakeJob& job);

}  // namespace probebake::client
