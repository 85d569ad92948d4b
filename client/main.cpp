// probebake: bake locally, inspect volumes, and drive a probebake-server (docs/service.md).
//
//   probebake bake JOB.json -o OUT.vdb [--threads N] [--json]
//                  [--shard I/N [--blob-dir D] [--progress-file F] [--expect-job-digest D]]
//   probebake plan JOB.json --shards N [--json]
//   probebake merge PART.vdb... -o OUT.vdb
//   probebake relight VOLUME.vdb (--environment MAP|SH.json | --uniform R,G,B) [--up Y|Z]
//                     [--scale S] [--rotate DEGREES] -o OUT.vdb
//   probebake inspect OUT.vdb [--json] [--slice AXIS=VALUE -o PNG]
//   probebake sample OUT.vdb --points POINTS.json
//   probebake export OUT.vdb --format threejs|unity|textures -o FILE.json
//   probebake view OUT.vdb [--scene JOB.json] [--exposure X] -o view.html
//   probebake submit JOB.json [--wait] [-o OUT.vdb] [--skip-cache] [--request-id ID]
//   probebake watch NAME | status NAME | fetch NAME -o OUT.vdb | cancel NAME | delete NAME | list
//   client options: --server ADDR ($PROBEBAKE_SERVER, default 127.0.0.1:50051),
//                   --token-file F ($PROBEBAKE_TOKEN), --tls, --tls-ca F, --json
//
// Exit codes: 0 success; 2 bad usage or bad input (the message names the file and field);
// 3 the job failed or was cancelled; 4 could not reach or authenticate to the server; 1 other
// failures.
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <random>
#include <string_view>

#include <CLI/CLI.hpp>

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "client/client.h"
#include "client/progress.h"

#include "probebake/bake/bake.h"
#include "probebake/bake/relight.h"
#include "probebake/base/log.h"
#include "probebake/engines/engine_export.h"
#include "probebake/engines/viewer_page.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/file_refs.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"
#include "probebake/job/validate.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/volume/irradiance_slice.h"
#include "probebake/volume/probe_sampler.h"
#include "probebake/volume/sample_points.h"
#include "probebake/volume/vdb_io.h"
#include "probebake/volume/volume_inspect.h"
#include "probebake/volume/volume_merge.h"
#include "runtime/asset_check.h"
#include "runtime/files.h"
#include "runtime/job_state.h"
#include "runtime/shard_plan.h"
#include "runtime/shard_progress.h"

namespace probebake {
// The viewer's JavaScript, embedded at build time (web/CMakeLists.txt); empty without it.
extern const std::string_view kViewerBundle;
}  // namespace probebake

namespace probebake::client {
namespace {

std::atomic<bool> gInterrupted{false};

extern "C" void OnInterrupt(int) {
  gInterrupted.store(true);
}

int Fail(int code, const std::string& message) {
  std::fprintf(stderr, "probebake: %s\n", message.c_str());
  return code;
}

int Fail(const absl::Status& status, const std::string& context = "") {
  std::string message(status.message());
  if (!context.empty()) {
    // Prefix every line (validation reports one error per line) with the file.
    std::string prefixed;
    for (absl::string_view line : absl::StrSplit(message, '\n'))
      absl::StrAppend(&prefixed, prefixed.empty() ? "" : "\n", context, ": ", line);
    message = prefixed;
  }
  return Fail(ExitCodeFor(status), message);
}

int ExitCodeForJob(const v1::BakeJob& job) {
  return job.state() == v1::BakeJob::FAILED || job.state() == v1::BakeJob::CANCELLED
             ? kExitJobFailed
             : kExitOk;
}

struct ClientFlags {
  std::string server;
  std::string tokenFile;
  std::string tlsCa;
  bool tls = false;
  bool json = false;
};

void AddClientFlags(CLI::App* command, ClientFlags* flags) {
  command->add_option("--server", flags->server,
                      "Server host:port (default $PROBEBAKE_SERVER or 127.0.0.1:50051)");
  command->add_option("--token-file", flags->tokenFile,
                      "File with the bearer token (without it: the token itself from "
                      "$PROBEBAKE_TOKEN)");
  command->add_flag("--tls", flags->tls, "Connect with TLS (system roots unless --tls-ca)");
  command->add_option("--tls-ca", flags->tlsCa, "PEM root certificates for TLS");
  command->add_flag("--json", flags->json, "One JSON object per line on stdout");
}

absl::StatusOr<std::unique_ptr<Client>> ConnectFrom(const ClientFlags& flags) {
  ConnectOptions options;
  const char* envServer = std::getenv("PROBEBAKE_SERVER");
  options.server = !flags.server.empty()       ? flags.server
                   : (envServer && *envServer) ? envServer
                                               : "127.0.0.1:50051";
  if (absl::Status address = CheckServerAddress(options.server); !address.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(
        flags.server.empty() ? "$PROBEBAKE_SERVER" : "--server", ": ", address.message()));
  }
  if (!flags.tokenFile.empty()) {
    absl::StatusOr<std::string> token = runtime::ReadWholeFile(flags.tokenFile);
    if (!token.ok())
      return absl::InvalidArgumentError(
          absl::StrCat("--token-file: ", std::string(token.status().message())));
    options.token = std::string(absl::StripAsciiWhitespace(*token));
  } else if (const char* envToken = std::getenv("PROBEBAKE_TOKEN")) {
    options.token = std::string(absl::StripAsciiWhitespace(envToken));
  }
  options.tls = flags.tls;
  options.tlsCaFile = flags.tlsCa;
  return Client::Connect(options);
}

JobLimits LimitsFrom(const v1::JobLimits& l) {
  JobLimits limits;
  limits.maxProbes = l.max_probes();
  limits.maxTriangles = l.max_triangles();
  limits.maxSamplesPerProbe = l.max_samples_per_probe();
  limits.maxShOrder = l.max_sh_order();
  limits.maxDepth = l.max_depth();
  limits.maxLights = l.max_lights();
  limits.maxAssetBytes = l.max_asset_bytes();
  limits.maxEnvironmentPixels = l.max_environment_pixels();
  limits.maxTexturePixels = l.max_texture_pixels();
  return limits;
}

// ---- bake (local) ----

// Before work that ends in writing `out`: kExitUsage with the reason if it cannot be written (a
// mistyped path fails at once, not after the bake), else kExitOk.
int CheckOutput(const std::string& out) {
  if (absl::Status writable = CheckOutputWritable(out); !writable.ok())
    return Fail(kExitUsage, std::string(writable.message()));
  return kExitOk;
}

// A job's mesh and map files are imported in a child first (runtime/asset_check.h): a file that
// crashes or hangs the importer is reported with its field instead of taking the CLI with it.
constexpr std::chrono::seconds kAssetCheckTimeout{600};

// This executable's path for the child. Resolved rather than "/proc/self/exe" itself: under a
// runner such as valgrind that link names the runner, which does not know `check-assets`. The
// CLI lives for one command, so the file cannot have been replaced since it started; if the
// link cannot be read, the link it is.
std::string SelfExecutable() {
  std::error_code error;
  std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", error);
  if (error || !std::filesystem::is_regular_file(self, error)) return "/proc/self/exe";
  return self.string();
}

// What a bake of one shard of a sharded bake (docs/cluster.md) is told besides the job file.
struct ShardFlags {
  std::string shard;            // "I/N"; empty: the whole grid
  std::string blobDir;          // blobs the job refers to, as <blobDir>/<sha256>
  std::string progressFile;     // rewritten with the shard's progress (runtime/shard_progress.h)
  std::string expectJobDigest;  // refuse to bake when the job's digest differs
};

// The job of `jobPath`, its assets read from files beside it and, with a blob folder, from
// blobs there; its mesh files taken from `imports` when given (an asset check's). Error lines
// start with the path.
absl::StatusOr<BakeJob> LoadJob(const std::string& jobPath, const std::string& blobDir,
                                const MeshImports* imports = nullptr) {
  if (blobDir.empty()) return LoadBakeJob(jobPath, JobLimits(), {nullptr, imports});
  absl::StatusOr<v1::JobSpec> spec = ReadJobFile(jobPath);
  if (!spec.ok()) return spec.status();
  const JobLimits limits;
  absl::StatusOr<BakeJob> job =
      BuildBakeJob(*spec, LocalAssetSource(JobFileDir(jobPath), blobDir, limits.maxAssetBytes),
                   limits, {nullptr, imports});
  if (job.ok()) return job;
  std::string message;
  for (absl::string_view line : absl::StrSplit(job.status().message(), '\n'))
    absl::StrAppend(&message, message.empty() ? "" : "\n", jobPath, ": ", line);
  return absl::Status(job.status().code(), message);
}

// Writes the shard's progress file, at most once a second but for stage changes.
class ShardProgressFile {
 public:
  ShardProgressFile(const std::string& path, int shard, int shards) : path_(path) {
    progress_.shard = shard;
    progress_.shards = shards;
    progress_.pid = getpid();
    char host[256] = {};
    gethostname(host, sizeof host - 1);
    progress_.host = host;
  }
  void Stage(const std::string& stage) {
    progress_.stage = stage;
    Write();
  }
  void Update(const BakeProgress& p) {
    progress_.probesDone = p.probesDone;
    progress_.probesTotal = p.probesTotal;
    progress_.samples = p.samples;
    progress_.rays = p.rays;
    progress_.elapsedSeconds = p.elapsedSeconds;
    const auto now = std::chrono::steady_clock::now();
    if (p.probesDone < p.probesTotal && now - written_ < std::chrono::seconds(1)) return;
    Write();
  }

 private:
  void Write() {
    if (path_.empty()) return;
    written_ = std::chrono::steady_clock::now();
    // A progress file that cannot be written costs the display, not the bake.
    if (absl::Status w = runtime::WriteFileAtomic(path_, runtime::ShardProgressJson(progress_));
        !w.ok())
      Logger("bake")->warn("--progress-file: {}", std::string(w.message()));
  }
  std::string path_;
  runtime::ShardProgress progress_;
  std::chrono::steady_clock::time_point written_{};
};

int RunBake(const std::string& jobPath, const std::string& out, int threads, bool json,
            const ShardFlags& shardFlags) {
  int shard = 0, shards = 0;
  if (!shardFlags.shard.empty()) {
    if (absl::Status parsed = runtime::ParseShardSpec(shardFlags.shard, "--shard", &shard, &shards);
        !parsed.ok())
      return Fail(kExitUsage, std::string(parsed.message()));
  }
  ShardProgressFile progressFile(shardFlags.progressFile, shard, std::max(shards, 1));
  progressFile.Stage("planning");
  // The job's files are imported by the check's child only; this process builds from its imports.
  std::optional<MeshImports> imports;
  if (absl::StatusOr<v1::JobSpec> spec = ReadJobFile(jobPath);
      spec.ok() && (!ListFileReferences(*spec).empty() || !shardFlags.blobDir.empty())) {
    const std::filesystem::path importsFile =
        std::filesystem::temp_directory_path() /
        absl::StrCat("probebake-imports-", getpid(), "-", std::random_device{}());
    std::vector<std::string> argv = {SelfExecutable(), "check-assets", jobPath, "--imports-out",
                                     importsFile.string()};
    if (!shardFlags.blobDir.empty()) {
      argv.push_back("--blob-dir");
      argv.push_back(shardFlags.blobDir);
    }
    absl::StatusOr<MeshImports> checked =
        runtime::RunAssetCheck(std::move(argv), kAssetCheckTimeout, importsFile);
    if (!checked.ok()) return Fail(checked.status(), jobPath);
    imports = std::move(*checked);
  }
  absl::StatusOr<BakeJob> job = LoadJob(jobPath, shardFlags.blobDir, imports ? &*imports : nullptr);
  if (!job.ok()) return Fail(kExitUsage, std::string(job.status().message()));
  if (!shardFlags.expectJobDigest.empty() && job->jobDigest != shardFlags.expectJobDigest)
    return Fail(kExitUsage,
                absl::StrCat(jobPath, ": the job digest is ", job->jobDigest, ", not ",
                             shardFlags.expectJobDigest,
                             " (--expect-job-digest): this probebake bakes other bits than the "
                             "one that planned the job; install the same version everywhere"));
  if (const int code = CheckOutput(out); code != kExitOk) return code;
  // Ctrl-C cancels the bake cleanly (exit 3) instead of killing it.
  struct sigaction action = {};
  action.sa_handler = OnInterrupt;
  sigaction(SIGINT, &action, nullptr);
  if (shards > 0) {
    absl::StatusOr<runtime::ShardPlan> plan = runtime::PlanShards(*job, shards, threads);
    if (!plan.ok())
      return Fail(kExitUsage,
                  absl::StrCat("--shard ", shardFlags.shard, ": ", plan.status().message()));
    const runtime::ShardBox& box = plan->shards[size_t(shard)];
    job->grid = runtime::ShardGrid(job->grid, box);
    Logger("bake")->info(
        "shard {} of {}: grid points ({}, {}, {}) + ({}, {}, {}), {} probes expected", shard,
        shards, box.first[0], box.first[1], box.first[2], box.counts[0], box.counts[1],
        box.counts[2], box.expectedProbes);
  }
  progressFile.Stage("baking");
  ProgressView view(ProgressView::Choose(json));
  BakeOptions options;
  options.threads = threads;
  options.cancel = &gInterrupted;
  options.progress = [&](const BakeProgress& p) {
    view.Update(p);
    progressFile.Update(p);
  };
  absl::StatusOr<ProbeVolume> volume = Bake(*job, options);
  view.Done();
  if (!volume.ok()) {
    if (absl::IsCancelled(volume.status())) return Fail(kExitJobFailed, "bake cancelled");
    return Fail(kExitJobFailed,
                absl::StrCat(jobPath, ": bake failed: ", std::string(volume.status().message())));
  }
  BakeStats stats = volume->stats;
  progressFile.Stage("writing");
  absl::Status written = WriteProbeVolume(out, std::move(*volume), VolumeMetadataFor(*job));
  if (!written.ok()) return Fail(kExitUsage, std::string(written.message()));
  progressFile.Stage("done");
  if (json) {
    std::printf(
        "{\"output\":%s,\"stats\":{\"wallSeconds\":%.6g,\"threads\":%d,\"probes\":%lld,"
        "\"samples\":%lld,\"rays\":%lld,\"invalidProbes\":%lld}}\n",
        JsonQuote(out).c_str(), stats.wallSeconds, stats.threads, (long long)stats.probes,
        (long long)stats.samples, (long long)stats.rays, (long long)stats.invalidProbes);
  } else {
    std::fprintf(stderr,
                 "wrote %s: %lld probes (%lld invalid), %lld samples, %lld rays in %.2f s\n",
                 out.c_str(), (long long)stats.probes, (long long)stats.invalidProbes,
                 (long long)stats.samples, (long long)stats.rays, stats.wallSeconds);
  }
  return kExitOk;
}

// ---- plan ----

// Prints how `probebake bake --shard I/N` splits the job's grid (runtime/shard_plan.h).
int RunPlan(const std::string& jobPath, int shards, int threads, bool json) {
  absl::StatusOr<BakeJob> job = LoadBakeJob(jobPath, JobLimits());
  if (!job.ok()) return Fail(kExitUsage, std::string(job.status().message()));
  absl::StatusOr<runtime::ShardPlan> plan = runtime::PlanShards(*job, shards, threads);
  if (!plan.ok()) return Fail(kExitUsage, absl::StrCat("--", plan.status().message()));
  if (json)
    std::printf("%s\n", runtime::ShardPlanJson(*plan, job->grid).c_str());
  else
    std::printf("%s", runtime::FormatShardPlan(*plan, job->grid).c_str());
  return kExitOk;
}

// ---- inspect ----

// A volume with a sky transfer holds the local lights alone in its radiance: tools that read
// radiance say so (they are not wrong, only unlit by a sky until relit).
void NoteSkyTransfer(const std::string& path, const ProbeVolume& volume) {
  if (volume.skyTransferOrder > 0)
    std::fprintf(stderr,
                 "probebake: note: %s has a sky transfer: its radiance holds the local lights "
                 "only; probebake relight it for a sky first\n",
                 path.c_str());
}

int RunInspect(const std::string& path, bool json, const std::string& slice,
               const std::string& png) {
  if (!slice.empty()) {
    if (png.empty()) return Fail(kExitUsage, "--slice needs -o PNG");
    SliceOptions options;
    if (absl::Status parsed = ParseSliceSpec(slice, &options); !parsed.ok())
      return Fail(kExitUsage, std::string(parsed.message()));
    absl::StatusOr<ProbeVolumeFile> file = ReadProbeVolume(path);
    if (!file.ok()) return Fail(kExitUsage, std::string(file.status().message()));
    NoteSkyTransfer(path, file->volume);
    if (absl::Status written = WriteIrradianceSlice(file->volume, options, png); !written.ok())
      return Fail(kExitUsage, std::string(written.message()));
    if (!json) std::fprintf(stderr, "wrote %s\n", png.c_str());
    return kExitOk;
  }
  absl::StatusOr<VolumeReport> report = InspectProbeVolume(path);
  if (!report.ok()) return Fail(kExitUsage, std::string(report.status().message()));
  if (json)
    std::printf("%s\n", VolumeReportJson(*report).c_str());
  else
    std::printf("%s\nsee it in a browser: probebake view %s [--scene JOB.json] -o view.html\n",
                FormatVolumeReport(*report).c_str(), path.c_str());
  return kExitOk;
}

// ---- export, view (docs/engines.md) ----

int RunExport(const std::string& path, const std::string& format, const std::string& out) {
  absl::StatusOr<EngineFormat> parsed = ParseEngineFormat(format);
  if (!parsed.ok()) return Fail(kExitUsage, std::string(parsed.status().message()));
  if (const int code = CheckOutput(out); code != kExitOk) return code;
  absl::StatusOr<ProbeVolumeFile> file = ReadProbeVolume(path);
  if (!file.ok()) return Fail(kExitUsage, std::string(file.status().message()));
  NoteSkyTransfer(path, file->volume);
  if (absl::Status written = WriteEngineExport(file->volume, *parsed, out); !written.ok())
    return Fail(kExitUsage, absl::StrCat(path, ": ", written.message()));
  std::fprintf(stderr, "wrote %s\n", out.c_str());
  return kExitOk;
}

int RunView(const std::string& path, const std::string& jobPath, double exposure,
            const std::string& out) {
  if (kViewerBundle.empty())
    return Fail(kExitUsage,
                "view: this probebake was built without the viewer (-DPROBEBAKE_VIEWER=OFF)");
  if (const int code = CheckOutput(out); code != kExitOk) return code;
  absl::StatusOr<ProbeVolumeFile> file = ReadProbeVolume(path);
  if (!file.ok()) return Fail(kExitUsage, std::string(file.status().message()));
  NoteSkyTransfer(path, file->volume);
  std::optional<BakeJob> job;
  if (!jobPath.empty()) {
    absl::StatusOr<BakeJob> loaded = LoadBakeJob(jobPath, JobLimits());
    if (!loaded.ok()) return Fail(loaded.status(), "--scene " + jobPath);
    job = std::move(*loaded);
  }
  ViewerOptions options;
  options.exposure = exposure;
  absl::StatusOr<std::string> html =
      ViewerPageHtml(file->volume, job ? &job->scene : nullptr, kViewerBundle, options);
  if (!html.ok()) return Fail(kExitUsage, absl::StrCat(path, ": ", html.status().message()));
  if (absl::Status written = WriteTextFileAtomically(out, *html); !written.ok())
    return Fail(kExitUsage, std::string(written.message()));
  std::fprintf(stderr, "wrote %s\n", out.c_str());
  return kExitOk;
}

// ---- sample ----

// Prints the lighting the reference sampler (probe_sampler.h) reads at each point of
// `pointsPath`, one JSON object per line (sample_points.h).
int RunSample(const std::string& path, const std::string& pointsPath) {
  std::ifstream in(pointsPath, std::ios::binary);
  if (!in) return Fail(kExitUsage, pointsPath + ": cannot be read");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  absl::StatusOr<std::vector<SamplePoint>> points = ParseSamplePoints(text);
  if (!points.ok())
    return Fail(kExitUsage, pointsPath + ": " + std::string(points.status().message()));
  absl::StatusOr<ProbeVolumeFile> file = ReadProbeVolume(path);
  if (!file.ok()) return Fail(kExitUsage, std::string(file.status().message()));
  NoteSkyTransfer(path, file->volume);
  const ProbeSampler sampler(file->volume);
  for (const SamplePoint& p : *points)
    std::printf("%s\n", SampleJson(p, sampler.Sample(p.position, p.normal)).c_str());
  return kExitOk;
}

// ---- merge ----

// Merges the volumes of a sharded bake (volume_merge.h) into `out`.
int RunMerge(const std::vector<std::string>& inputs, const std::string& out) {
  if (const int code = CheckOutput(out); code != kExitOk) return code;
  std::vector<VolumePart> parts;
  for (const std::string& input : inputs) {
    absl::StatusOr<ProbeVolumeFile> file = ReadProbeVolume(input);
    if (!file.ok()) return Fail(kExitUsage, std::string(file.status().message()));
    parts.push_back({input, std::move(*file)});
  }
  absl::StatusOr<ProbeVolumeFile> merged = MergeProbeVolumes(std::move(parts));
  if (!merged.ok()) return Fail(kExitUsage, std::string(merged.status().message()));
  const int64_t probes =
      std::count(merged->volume.active.begin(), merged->volume.active.end(), uint8_t{1});
  const ProbeGrid& g = merged->volume.grid;
  if (absl::Status written = WriteProbeVolume(out, std::move(merged->volume), merged->meta);
      !written.ok())
    return Fail(kExitUsage, std::string(written.message()));
  std::fprintf(stderr, "wrote %s: %lld probes from %zu volumes, grid %d x %d x %d\n", out.c_str(),
               (long long)probes, inputs.size(), g.counts[0], g.counts[1], g.counts[2]);
  return kExitOk;
}

// ---- relight ----

struct RelightFlags {
  std::string environment;  // a map file, or .json SH coefficients
  std::string uniform;      // "r,g,b"
  std::string up = "Y";
  double scale = 1;
  double rotate = 0;
};

// Sky SH coefficients from a JSON file {"coefficients": [[r, g, b], ...]}: (Ls+1)^2 RGB triples
// in the volume's SH convention (docs/spherical-harmonics.md), radiance units.
absl::StatusOr<std::vector<Vec3d>> ReadSkyShJson(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::InvalidArgumentError(path + ": cannot be read");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  google::protobuf::Struct root;
  if (!google::protobuf::util::JsonStringToMessage(text, &root).ok())
    return absl::InvalidArgumentError(path + ": not a JSON object");
  const auto field = root.fields().find("coefficients");
  if (field == root.fields().end() || !field->second.has_list_value())
    return absl::InvalidArgumentError(path + ": coefficients: expected a list of [r, g, b]");
  std::vector<Vec3d> sky;
  for (const google::protobuf::Value& v : field->second.list_value().values()) {
    const std::string at = path + ": coefficients[" + std::to_string(sky.size()) + "]";
    if (!v.has_list_value() || v.list_value().values_size() != 3)
      return absl::InvalidArgumentError(at + ": expected [r, g, b]");
    Vec3d c;
    for (int ch = 0; ch < 3; ++ch) {
      const google::protobuf::Value& x = v.list_value().values(ch);
      if (!x.has_number_value() || !std::isfinite(x.number_value()))
        return absl::InvalidArgumentError(at + ": expected three finite numbers");
      c[ch] = x.number_value();
    }
    sky.push_back(c);
  }
  size_t order = 0;
  while ((order + 1) * (order + 1) < sky.size()) ++order;
  if (sky.empty() || (order + 1) * (order + 1) != sky.size() || int(order) > kMaxShOrder)
    return absl::InvalidArgumentError(path + ": coefficients: " + std::to_string(sky.size()) +
                                      " entries, expected (L+1)^2 for an order L in [0, " +
                                      std::to_string(kMaxShOrder) + "]");
  return sky;
}

// Relights a volume baked with a sky transfer (probebake/bake/relight.h) for the sky given.
int RunRelight(const std::string& input, const RelightFlags& f, const std::string& out) {
  if (f.environment.empty() == f.uniform.empty())
    return Fail(kExitUsage, "relight: give one of --environment and --uniform");
  if (const int code = CheckOutput(out); code != kExitOk) return code;
  absl::StatusOr<ProbeVolumeFile> file = ReadProbeVolume(input);
  if (!file.ok()) return Fail(kExitUsage, std::string(file.status().message()));
  ProbeVolume& volume = file->volume;
  if (volume.skyTransferOrder <= 0)
    return Fail(kExitUsage, input + ": no sky transfer (bake with settings.skyTransfer.order)");
  const int order = volume.skyTransferOrder;

  const auto start = std::chrono::steady_clock::now();
  std::vector<Vec3d> sky;
  int skyOrder = order;
  if (absl::EndsWithIgnoreCase(f.environment, ".json")) {
    absl::StatusOr<std::vector<Vec3d>> read = ReadSkyShJson(f.environment);
    if (!read.ok()) return Fail(kExitUsage, std::string(read.status().message()));
    sky = std::move(*read);
    for (Vec3d& c : sky) c = c * f.scale;
    skyOrder = int(std::lround(std::sqrt(double(sky.size())))) - 1;
  } else {
    v1::Environment spec;
    if (!f.uniform.empty()) {
      const std::vector<std::string> parts = absl::StrSplit(f.uniform, ',');
      double rgb[3];
      if (parts.size() != 3 || !absl::SimpleAtod(parts[0], &rgb[0]) ||
          !absl::SimpleAtod(parts[1], &rgb[1]) || !absl::SimpleAtod(parts[2], &rgb[2]))
        return Fail(kExitUsage, "--uniform: expected R,G,B (three numbers)");
      for (double x : rgb) spec.mutable_uniform()->add_radiance(x * f.scale);
    } else {
      const std::filesystem::path path = std::filesystem::absolute(f.environment);
      v1::EnvironmentMap* map = spec.mutable_map();
      map->set_file(path.filename().string());
      map->set_scale(f.scale);
      if (f.up != "Y" && f.up != "Z") return Fail(kExitUsage, "--up: expected Y or Z");
      map->set_up(f.up == "Z" ? v1::EnvironmentMap::Z : v1::EnvironmentMap::Y);
    }
    const JobLimits limits;
    absl::StatusOr<Environment> env = LoadEnvironment(
        spec,
        LocalAssetSource(std::filesystem::absolute(f.environment.empty() ? "." : f.environment)
                             .parent_path()
                             .string(),
                         "", limits.maxAssetBytes),
        limits);
    if (!env.ok()) return Fail(env.status(), f.environment.empty() ? "--uniform" : f.environment);
    sky = ProjectEnvironmentSh(*env, order);
  }
  if (f.rotate != 0) {
    absl::StatusOr<std::vector<Vec3d>> rotated = RotateSkyAboutUp(sky, skyOrder, f.rotate);
    if (!rotated.ok()) return Fail(kExitUsage, std::string(rotated.status().message()));
    sky = std::move(*rotated);
  }
  const double skySeconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // The irradiance window as baked (the volume's recorded settings).
  RelightOptions options;
  v1::BakeSettings baked;
  google::protobuf::util::JsonParseOptions lenient;
  lenient.ignore_unknown_fields = true;
  if (google::protobuf::util::JsonStringToMessage(file->meta.settingsJson, &baked, lenient).ok()) {
    const BakeSettings resolved = ResolveSettings(baked);
    options.window = resolved.window;
    options.windowWidth = resolved.windowWidth;
  }
  const auto relightStart = std::chrono::steady_clock::now();
  absl::StatusOr<ProbeVolume> relit = Relight(volume, sky, options);
  if (!relit.ok()) return Fail(kExitUsage, std::string(relit.status().message()));
  const double relightSeconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - relightStart).count();
  const int64_t probes = std::count(volume.active.begin(), volume.active.end(), uint8_t{1});
  if (absl::Status written = WriteProbeVolume(out, *std::move(relit), file->meta); !written.ok())
    return Fail(kExitUsage, std::string(written.message()));
  std::fprintf(stderr,
               "wrote %s: %lld probes relit (order %d transfer, sky order %d): sky %.3f s, "
               "relight %.3f s\n",
               out.c_str(), (long long)probes, order, skyOrder, skySeconds, relightSeconds);
  return kExitOk;
}

// ---- client commands ----

// Watches until final, showing progress; 0 / 3 by the final state.
int WatchAndReport(Client& client, const std::string& name, ProgressView& view,
                   v1::BakeJob* final) {
  absl::StatusOr<v1::BakeJob> job =
      client.Watch(name, [&](const v1::BakeJob& update) { view.Update(update); });
  view.Done();
  if (!job.ok()) return Fail(job.status(), name);
  *final = *job;
  return ExitCodeForJob(*job);
}

int Fetch(Client& client, const v1::BakeJob& job, const std::string& out, ProgressView& view) {
  if (job.state() != v1::BakeJob::SUCCEEDED) {
    if (runtime::IsFinal(job.state()))
      return Fail(kExitJobFailed, absl::StrCat(JobSummary(job), "; nothing to fetch"));
    return Fail(kExitUsage,
                absl::StrCat(job.name(), " has not finished (",
                             v1::BakeJob::State_Name(job.state()), "); watch it first"));
  }
  absl::Status fetched =
      client.FetchBlob(job.result().volume(), out,
                       [&](int64_t done, int64_t total) { view.Bytes("fetch", done, total); });
  view.Done();
  // The job says SUCCEEDED, so a volume the server cannot find is the server's loss, not bad
  // input from the caller: exit 1, not 2.
  if (absl::IsNotFound(fetched))
    return Fail(kExitFailure, absl::StrCat(job.name(), ": the server no longer has its volume (",
                                           fetched.message(), ")"));
  if (!fetched.ok()) return Fail(fetched, out);
  if (view.mode() == ProgressView::Mode::kJson)
    std::printf(
        "{\"name\":\"%s\",\"output\":%s,\"volume\":{\"hash\":\"%s\",\"sizeBytes\":\"%lld\"}}\n",
        job.name().c_str(), JsonQuote(out).c_str(), job.result().volume().hash().c_str(),
        (long long)job.result().volume().size_bytes());
  else
    std::fprintf(stderr, "wrote %s (%lld bytes, sha256 verified)\n", out.c_str(),
                 (long long)job.result().volume().size_bytes());
  return kExitOk;
}

// The job must fit in one CreateBakeJob message (files travel apart, as blobs): otherwise the
// transport refuses it with a bare "larger than max". Names the largest inline mesh, what usually
// makes a job that large.
absl::Status FitsInOneMessage(const v1::JobSpec& spec, int64_t maxMessageBytes) {
  // Room for blob digests replacing file paths; the server keeps kJobRecordReserve of its message
  // limit for the rest of a job's record.
  constexpr int64_t kOverhead = 4096;
  const int64_t bytes = int64_t(spec.ByteSizeLong()) + kOverhead;
  maxMessageBytes -= runtime::kJobRecordReserve;
  if (maxMessageBytes <= 0 || bytes <= maxMessageBytes) return absl::OkStatus();
  int largest = -1;
  for (int i = 0; i < spec.scene().meshes_size(); ++i) {
    if (largest < 0 ||
        spec.scene().meshes(i).ByteSizeLong() > spec.scene().meshes(largest).ByteSizeLong())
      largest = i;
  }
  std::string hint = "; large inline meshes belong in mesh files, which are uploaded as blobs";
  if (largest >= 0) {
    hint = absl::StrCat("; the largest part is scene.meshes[", largest, "] (",
                        spec.scene().meshes(largest).ByteSizeLong(),
                        " bytes): put it in a mesh file, which is uploaded as a blob");
  }
  return absl::InvalidArgumentError(absl::StrCat(
      "the job is about ", bytes,
      " bytes as a request, over the server's message limit for a job of ", maxMessageBytes,
      " bytes (max_message_bytes less ", runtime::kJobRecordReserve, " for its record)", hint));
}

int RunSubmit(const ClientFlags& flags, const std::string& jobPath, bool wait,
              const std::string& out, bool skipCache, std::string requestId) {
  absl::StatusOr<v1::JobSpec> spec = ReadJobFile(jobPath);
  if (!spec.ok()) return Fail(kExitUsage, std::string(spec.status().message()));
  if (!out.empty()) {
    if (const int code = CheckOutput(out); code != kExitOk) return code;
  }
  auto client = ConnectFrom(flags);
  if (!client.ok()) return Fail(client.status());
  absl::StatusOr<v1::ServerCapabilities> capabilities = (*client)->GetCapabilities();
  if (!capabilities.ok()) return Fail(capabilities.status());
  // The server's limits, checked before anything is uploaded.
  if (absl::Status valid = ValidateJobSpec(*spec, LimitsFrom(capabilities->job_limits()));
      !valid.ok())
    return Fail(valid, jobPath);
  if (absl::Status fits = FitsInOneMessage(*spec, capabilities->max_message_bytes()); !fits.ok())
    return Fail(fits, jobPath);
  absl::StatusOr<UploadReport> uploaded = (*client)->UploadJobFiles(JobFileDir(jobPath), &*spec);
  if (!uploaded.ok()) return Fail(uploaded.status(), jobPath);
  if (uploaded->files > 0)
    Logger("client")->info("{} file(s): {} uploaded ({} bytes), {} already on the server",
                           uploaded->files, uploaded->uploaded, uploaded->bytesSent,
                           uploaded->files - uploaded->uploaded);
  if (requestId.empty()) requestId = NewRequestId();
  absl::StatusOr<v1::BakeJob> job = (*client)->CreateJob(*spec, requestId, skipCache);
  if (!job.ok()) return Fail(NameUploadedFiles(job.status(), *uploaded), jobPath);
  ProgressView view(ProgressView::Choose(flags.json));
  if (flags.json) {
    std::printf("%s\n", JobJson(*job).c_str());
  } else {
    std::printf("%s\n", JobSummary(*job).c_str());
    view.Seen(*job);
  }
  std::fflush(stdout);
  if (!wait && out.empty()) return kExitOk;
  v1::BakeJob final = *job;
  if (!runtime::IsFinal(job->state())) {
    int code = WatchAndReport(**client, job->name(), view, &final);
    if (code != kExitOk) return code;
  }
  if (final.state() != v1::BakeJob::SUCCEEDED) return Fail(kExitJobFailed, JobSummary(final));
  return out.empty() ? kExitOk : Fetch(**client, final, out, view);
}

int RunWatch(const ClientFlags& flags, const std::string& name) {
  auto client = ConnectFrom(flags);
  if (!client.ok()) return Fail(client.status());
  ProgressView view(ProgressView::Choose(flags.json));
  v1::BakeJob final;
  int code = WatchAndReport(**client, name, view, &final);
  if (code == kExitJobFailed && !flags.json) Fail(code, JobSummary(final));
  return code;
}

int RunStatus(const ClientFlags& flags, const std::string& name) {
  auto client = ConnectFrom(flags);
  if (!client.ok()) return Fail(client.status());
  absl::StatusOr<v1::BakeJob> job = (*client)->GetJob(name);
  if (!job.ok()) return Fail(job.status());
  std::printf("%s\n", flags.json ? JobJson(*job).c_str() : JobSummary(*job).c_str());
  return ExitCodeForJob(*job);
}

int RunFetch(const ClientFlags& flags, const std::string& name, const std::string& out) {
  // A path that cannot take the volume (a missing folder, a directory) is refused before the
  // download, as bake and submit refuse it before the bake.
  if (const int code = CheckOutput(out); code != kExitOk) return code;
  auto client = ConnectFrom(flags);
  if (!client.ok()) return Fail(client.status());
  absl::StatusOr<v1::BakeJob> job = (*client)->GetJob(name);
  if (!job.ok()) return Fail(job.status());
  ProgressView view(ProgressView::Choose(flags.json));
  return Fetch(**client, *job, out, view);
}

int RunCancel(const ClientFlags& flags, const std::string& name) {
  auto client = ConnectFrom(flags);
  if (!client.ok()) return Fail(client.status());
  absl::StatusOr<v1::BakeJob> job = (*client)->CancelJob(name);
  if (!job.ok()) return Fail(job.status());
  if (!runtime::IsFinal(job->state())) {
    // Cancellation reaches the baker within a fraction of a second: wait for the final state.
    job = (*client)->Watch(
        name, [](const v1::BakeJob&) {}, std::chrono::seconds(10));
    if (!job.ok()) return Fail(job.status());
  }
  std::printf("%s\n", flags.json ? JobJson(*job).c_str() : JobSummary(*job).c_str());
  return kExitOk;
}

int RunDelete(const ClientFlags& flags, const std::string& name) {
  auto client = ConnectFrom(flags);
  if (!client.ok()) return Fail(client.status());
  if (absl::Status deleted = (*client)->DeleteJob(name); !deleted.ok()) return Fail(deleted);
  if (flags.json)
    std::printf("{\"deleted\":%s}\n", JsonQuote(name).c_str());
  else
    std::printf("%s deleted\n", name.c_str());
  return kExitOk;
}

int RunList(const ClientFlags& flags, int pageSize) {
  auto client = ConnectFrom(flags);
  if (!client.ok()) return Fail(client.status());
  std::string token;
  do {
    absl::StatusOr<v1::ListBakeJobsResponse> page = (*client)->ListJobs(pageSize, token);
    if (!page.ok()) return Fail(page.status());
    for (const v1::BakeJob& job : page->bake_jobs())
      std::printf("%s\n", flags.json ? JobJson(job).c_str() : JobSummary(job).c_str());
    token = page->next_page_token();
  } while (!token.empty());
  return kExitOk;
}

int Main(int argc, char** argv) {
  CLI::App app{"probebake: bake light probes locally or on a probebake-server"};
  app.footer(
      "Documentation, in the docs/ folder of the probebake repository:\n"
      "  job-format.md      the job file\n"
      "  volume-format.md   the .vdb a bake writes (inspect, merge)\n"
      "  engines.md         exports to engines and the viewer (export, view)\n"
      "  cluster.md         sharded bakes on a farm (plan, bake --shard, merge)\n"
      "  service.md         the server, and the commands that drive it (submit ... list)");
  app.require_subcommand(1);
  std::string logLevel = "warn";
  app.add_option("--log-level", logLevel, "trace, debug, info, warn, error or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}));

  std::string jobPath, out, path, name, slice, requestId;
  int threads = 0, pageSize = 100;
  bool json = false, wait = false, skipCache = false;
  ClientFlags flags;

  CLI::App* bake = app.add_subcommand("bake", "Bake JOB.json locally, in process");
  bake->add_option("job", jobPath, "Job file (docs/job-format.md)")->required();
  bake->add_option("-o,--output", out, "Probe volume to write (.vdb, docs/volume-format.md)")
      ->required();
  bake->add_option("--threads", threads, "Worker threads (0: all)")->check(CLI::NonNegativeNumber);
  bake->add_flag("--json", json, "Progress and result as JSON lines on stdout");
  ShardFlags shardFlags;
  bake->add_option("--shard", shardFlags.shard,
                   "I/N: bake only shard I (from 0) of the grid split in N (probebake plan; "
                   "join the parts with probebake merge)");
  bake->add_option("--blob-dir", shardFlags.blobDir,
                   "Folder of the blobs the job refers to, each named by its sha256");
  bake->add_option("--progress-file", shardFlags.progressFile,
                   "Keep this file rewritten with the bake's progress (JSON, docs/cluster.md)");
  bake->add_option("--expect-job-digest", shardFlags.expectJobDigest,
                   "Refuse to bake unless the job's digest is this one (a cluster's shards and "
                   "its planner must be the same baker)");

  int shardCount = 0;
  CLI::App* plan =
      app.add_subcommand("plan", "Show how JOB.json's grid splits into shards (bake --shard)");
  plan->add_option("job", jobPath, "Job file (docs/job-format.md)")->required();
  plan->add_option("--shards", shardCount, "Shards")->required()->check(CLI::PositiveNumber);
  plan->add_option("--threads", threads, "Worker threads of the pre-pass (0: all)")
      ->check(CLI::NonNegativeNumber);
  plan->add_flag("--json", json, "One JSON object on stdout");

  // The child of the local bake's asset check (runtime/asset_check.h); not for people.
  CLI::App* checkAssets = app.add_subcommand("check-assets");
  checkAssets->group("");
  checkAssets->add_option("job", jobPath)->required();
  std::string importsOut;
  checkAssets->add_option("--imports-out", importsOut)->required();
  std::string checkBlobDir;
  checkAssets->add_option("--blob-dir", checkBlobDir);
  CLI::App* inspect = app.add_subcommand("inspect", "Describe a probe volume file");
  inspect->add_option("volume", path, "Probe volume (.vdb, docs/volume-format.md)")->required();
  inspect->add_flag("--json", json, "One JSON object on stdout");
  inspect->add_option("--slice", slice, "AXIS=VALUE: render an irradiance slice to -o PNG");
  inspect->add_option("-o,--output", out, "PNG for --slice");

  std::string pointsPath;
  CLI::App* sample = app.add_subcommand(
      "sample", "Print the irradiance and radiance SH the reference sampler reads at points");
  sample->add_option("volume", path, "Probe volume (.vdb, docs/volume-format.md)")->required();
  sample
      ->add_option("--points", pointsPath,
                   "JSON array of {\"position\": [x, y, z], \"normal\": [x, y, z]}")
      ->required();
  std::string format, sceneJob;
  double exposure = 0;
  CLI::App* exportCmd =
      app.add_subcommand("export", "Write a volume's probes for an engine (docs/engines.md)");
  exportCmd->add_option("volume", path, "Probe volume (.vdb)")->required();
  exportCmd->add_option("--format", format, "threejs, unity or textures")->required();
  exportCmd->add_option("-o,--output", out, "File to write (.json)")->required();
  CLI::App* view = app.add_subcommand(
      "view", "Write a self-contained HTML page showing the probes (and the scene) in 3D");
  view->add_option("volume", path, "Probe volume (.vdb)")->required();
  view->add_option("--scene", sceneJob, "Job file whose meshes to show, lit by the probes");
  view->add_option("--exposure", exposure, "Colour scale before sRGB (default: automatic)")
      ->check(CLI::PositiveNumber);
  view->add_option("-o,--output", out, "Page to write (.html)")->required();

  RelightFlags relightFlags;
  CLI::App* relight = app.add_subcommand(
      "relight", "Relight a volume baked with settings.skyTransfer for another sky");
  relight->add_option("volume", path, "Probe volume with a sky transfer (.vdb)")->required();
  relight->add_option("--environment", relightFlags.environment,
                      "Sky: an environment map (OpenEXR or .hdr, lat-long or cube, as a job's "
                      "map), or SH coefficients (.json: {\"coefficients\": [[r,g,b], ...]})");
  relight->add_option("--uniform", relightFlags.uniform, "Sky: a uniform radiance R,G,B");
  relight->add_option("--up", relightFlags.up, "The map's up axis, Y (default) or Z");
  relight->add_option("--scale", relightFlags.scale, "Multiplies the sky (default 1)")
      ->check(CLI::NonNegativeNumber);
  relight->add_option("--rotate", relightFlags.rotate,
                      "Turn the sky about the up axis (world +Z), degrees counter-clockwise seen "
                      "from above");
  relight->add_option("-o,--output", out, "Relit probe volume to write (.vdb)")->required();

  std::vector<std::string> parts;
  CLI::App* merge =
      app.add_subcommand("merge", "Merge the volumes of sub-grids of one grid (a sharded bake)");
  merge->add_option("volumes", parts, "Sub-grid volumes (.vdb, docs/volume-format.md)")->required();
  merge->add_option("-o,--output", out, "Merged probe volume to write (.vdb)")->required();

  CLI::App* submit = app.add_subcommand("submit", "Upload JOB.json's files and queue the bake");
  submit->add_option("job", jobPath, "Job file (docs/job-format.md)")->required();
  submit->add_flag("--wait", wait, "Watch the job until it ends");
  submit->add_option("-o,--output", out, "Fetch the volume here when it succeeds (implies --wait)");
  submit->add_flag("--skip-cache", skipCache, "Bake even if the result cache has this job");
  submit->add_option("--request-id", requestId, "Idempotency key (default: a random one)");
  AddClientFlags(submit, &flags);

  CLI::App* watch = app.add_subcommand("watch", "Follow a job until it ends");
  watch->add_option("name", name, "bakeJobs/<id>")->required();
  AddClientFlags(watch, &flags);
  CLI::App* status = app.add_subcommand("status", "Show a job");
  status->add_option("name", name, "bakeJobs/<id>")->required();
  AddClientFlags(status, &flags);
  CLI::App* fetch = app.add_subcommand("fetch", "Download a job's volume (resumable)");
  fetch->add_option("name", name, "bakeJobs/<id>")->required();
  fetch->add_option("-o,--output", out, "Probe volume to write (.vdb)")->required();
  AddClientFlags(fetch, &flags);
  CLI::App* cancel = app.add_subcommand("cancel", "Cancel a job");
  cancel->add_option("name", name, "bakeJobs/<id>")->required();
  AddClientFlags(cancel, &flags);
  CLI::App* del = app.add_subcommand(
      "delete", "Forget a job that is not running (the server then frees its files)");
  del->add_option("name", name, "bakeJobs/<id>")->required();
  AddClientFlags(del, &flags);
  CLI::App* list = app.add_subcommand("list", "List jobs, oldest first");
  list->add_option("--page-size", pageSize, "Jobs per request")->check(CLI::PositiveNumber);
  AddClientFlags(list, &flags);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  }
  SetLogLevel(spdlog::level::from_str(logLevel));

  if (*checkAssets) {
    SetLogLevel(spdlog::level::warn);  // the bake that spawned it logs what matters
    return runtime::RunLocalAssetCheckChild(jobPath, checkBlobDir, importsOut, JobLimits());
  }
  if (*bake) return RunBake(jobPath, out, threads, json, shardFlags);
  if (*plan) return RunPlan(jobPath, shardCount, threads, json);
  if (*inspect) return RunInspect(path, json, slice, out);
  if (*sample) return RunSample(path, pointsPath);
  if (*exportCmd) return RunExport(path, format, out);
  if (*view) return RunView(path, sceneJob, exposure, out);
  if (*merge) return RunMerge(parts, out);
  if (*relight) return RunRelight(path, relightFlags, out);
  if (*submit) return RunSubmit(flags, jobPath, wait, out, skipCache, requestId);
  if (*watch) return RunWatch(flags, name);
  if (*status) return RunStatus(flags, name);
  if (*fetch) return RunFetch(flags, name, out);
  if (*cancel) return RunCancel(flags, name);
  if (*del) return RunDelete(flags, name);
  if (*list) return RunList(flags, pageSize);
  return kExitUsage;
}

}  // namespace
}  // namespace probebake::client

int main(int argc, char** argv) {
  return probebake::client::Main(argc, argv);
}
