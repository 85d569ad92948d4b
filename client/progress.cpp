#include "client/progress.h"

#include <unistd.h>

#include <cmath>

#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/time_util.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace probebake::client {

using google::protobuf::util::TimeUtil;

ProgressView::Mode ProgressView::Choose(bool json) {
  if (json) return Mode::kJson;
  return ::isatty(STDERR_FILENO) ? Mode::kBar : Mode::kLines;
}

std::string FormatDuration(double seconds) {
  if (!(seconds >= 0) || !std::isfinite(seconds)) return "?";
  int64_t s = int64_t(std::llround(seconds));
  if (s >= 3600) return absl::StrFormat("%d:%02d:%02d", s / 3600, (s / 60) % 60, s % 60);
  return absl::StrFormat("%d:%02d", s / 60, s % 60);
}

std::string JsonQuote(std::string_view text) {
  std::string quoted = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') {
      quoted += '\\';
      quoted += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      quoted += absl::StrFormat("\\u%04x", int(c));
    } else {
      quoted += c;
    }
  }
  return quoted + "\"";
}

std::string JobJson(const v1::BakeJob& job) {
  std::string json;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = false;
  (void)google::protobuf::util::MessageToJsonString(job, &json, options);
  return json;
}

std::string JobSummary(const v1::BakeJob& job) {
  std::string line = absl::StrCat(job.name(), " ", v1::BakeJob::State_Name(job.state()));
  const v1::BakeJobProgress& p = job.progress();
  if (p.probes_total() > 0)
    absl::StrAppend(&line, " ", p.probes_done(), "/", p.probes_total(), " probes");
  if (job.state() == v1::BakeJob::SUCCEEDED) {
    absl::StrAppend(&line, " volume sha256:", job.result().volume().hash(), "/",
                    job.result().volume().size_bytes());
    if (job.result().cached_result())
      absl::StrAppend(&line, " (cached result of ", job.result().source_job(), ")");
    else
      absl::StrAppend(&line, absl::StrFormat(" in %.2f s", job.result().stats().wall_seconds()));
  }
  if (job.has_error() && job.error().code() != 0)
    absl::StrAppend(&line, ": ", job.error().message());
  if (job.cancel_requested() && job.state() == v1::BakeJob::RUNNING)
    absl::StrAppend(&line, " (cancelling)");
  if (!p.waiting().empty() && job.state() == v1::BakeJob::RUNNING)
    absl::StrAppend(&line, " (", p.waiting(), ")");
  return line;
}

void ProgressView::Redraw(const std::string& line) {
  std::fprintf(stderr, "\r%s\x1b[K", line.c_str());
  std::fflush(stderr);
  barOpen_ = true;
}

void ProgressView::Done() {
  if (barOpen_) std::fprintf(stderr, "\n");
  barOpen_ = false;
}

void ProgressView::Bar(const std::string& label, int64_t done, int64_t total, double elapsedSeconds,
                       int64_t resumed, double etaSeconds, double errorEstimate,
                       int64_t errorUnknown) {
  constexpr int kWidth = 24;
  int filled = total > 0 ? int(kWidth * double(done) / double(total)) : 0;
  std::string bar = std::string(size_t(filled), '#') + std::string(size_t(kWidth - filled), '-');
  double rate = elapsedSeconds > 0 ? double(done - resumed) / elapsedSeconds : 0;
  std::string line = absl::StrFormat("%s [%s] %d/%d probes  %.1f probes/s  ETA %s", label, bar,
                                     done, total, rate, FormatDuration(etaSeconds));
  // Probes of unknown error are named, not averaged in (nor hidden).
  if (errorEstimate >= 0) {
    absl::StrAppend(&line, absl::StrFormat("  err %.2f%%", 100 * errorEstimate));
    if (errorUnknown > 0) absl::StrAppend(&line, absl::StrFormat(" (%d unknown)", errorUnknown));
  } else if (errorUnknown > 0) {
    absl::StrAppend(&line, absl::StrFormat("  err unknown (%d probes)", errorUnknown));
  }
  Redraw(line);
}

void ProgressView::Update(const v1::BakeJob& job) {
  if (mode_ == Mode::kJson) {
    std::printf("%s\n", JobJson(job).c_str());
    std::fflush(stdout);
    return;
  }
  const v1::BakeJobProgress& p = job.progress();
  // A wait begun or ended (a full disk on the server) is news like a state.
  bool stateChanged = int(job.state()) != lastState_ || p.waiting() != lastWaiting_;
  lastState_ = int(job.state());
  lastWaiting_ = p.waiting();
  if (mode_ == Mode::kLines || job.state() != v1::BakeJob::RUNNING || !p.waiting().empty()) {
    // A line per state; while running (lines mode) only when something changed.
    if (stateChanged) {
      Done();
      std::fprintf(stderr, "%s\n", JobSummary(job).c_str());
    }
    return;
  }
  Bar(job.name(), p.probes_done(), p.probes_total(),
      double(TimeUtil::DurationToMilliseconds(p.elapsed())) / 1000.0, p.probes_resumed(),
      p.has_eta() ? double(TimeUtil::DurationToMilliseconds(p.eta())) / 1000.0 : -1,
      p.has_error_estimate() ? p.error_estimate() : -1, p.probes_error_unknown());
}

void ProgressView::Update(const BakeProgress& p) {
  if (mode_ == Mode::kJson) {
    std::printf(
        "{\"probesDone\":%lld,\"probesTotal\":%lld,\"samples\":%lld,\"rays\":%lld,"
        "\"elapsedSeconds\":%.3f,\"etaSeconds\":%.3f,\"errorEstimate\":%.6g,"
        "\"probesErrorUnknown\":%lld}\n",
        (long long)p.probesDone, (long long)p.probesTotal, (long long)p.samples, (long long)p.rays,
        p.elapsedSeconds, p.etaSeconds, p.errorEstimate, (long long)p.probesErrorUnknown);
    std::fflush(stdout);
    return;
  }
  if (mode_ == Mode::kLines) return;  // a summary line follows the bake
  Bar("bake", p.probesDone, p.probesTotal, p.elapsedSeconds, 0, p.etaSeconds, p.errorEstimate,
      p.probesErrorUnknown);
}

void ProgressView::Bytes(const std::string& label, int64_t done, int64_t total) {
  if (mode_ != Mode::kBar) return;
  auto now = std::chrono::steady_clock::now();
  if (done < total && now - lastDraw_ < std::chrono::milliseconds(100)) return;
  lastDraw_ = now;
  Redraw(absl::StrFormat("%s %.1f / %.1f MB", label, double(done) / 1e6, double(total) / 1e6));
}

}  // namespace probebake::client
