// probebake-server: the gRPC bake service (docs/service.md).
//
//   probebake-server --listen ADDR --data-dir DIR [--threads N] [--max-concurrent-jobs N]
//                    [--max-queued-jobs N] [--token-file F] [--tls-cert F --tls-key F]
//                    [--max-probes N ...] [--asset-check-timeout S] [--config FILE]
//                    [--port-file F] [--log-level L]
//                    [--backend local|slurm --slurm-shared-dir DIR (--slurm-shards N |
//                     --slurm-probes-per-shard P) [--slurm-partition P] [--slurm-retries R] ...]
//
// Exit codes: 0 after a graceful shutdown (SIGTERM or SIGINT), 2 for bad flags, 1 when the
// server cannot start (data folder in use, port taken, unreadable token or certificate).
#include <signal.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "probebake/base/log.h"
#include "probebake/job/job.h"
#include "runtime/files.h"
#include "server/asset_check.h"
#include "server/bake_backend.h"
#include "server/blob_store.h"
#include "server/server.h"
#include "server/slurm_backend.h"

namespace {

constexpr int kExitStartFailure = 1;
constexpr int kExitUsage = 2;

}  // namespace

int main(int argc, char** argv) {
  using probebake::Logger;
  namespace srv = probebake::server;

  srv::ServerOptions options;
  std::string dataDir, tokenFile, tlsCert, tlsKey, portFile, logLevel = "info";
  CLI::App app{"probebake-server: bakes light probes for gRPC clients (probebake.v1)"};
  app.set_config("--config", "", "TOML or INI file with any of these options (flags win)");
  app.add_option("--listen", options.listen, "host:port to listen on (port 0: any free port)")
      ->capture_default_str();
  app.add_option("--data-dir", dataDir, "Folder of the job store, blob store and checkpoints")
      ->required();
  app.add_option("--threads", options.threadsPerJob,
                 "Worker threads per running bake (0: every hardware thread)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-concurrent-jobs", options.maxConcurrentJobs, "Jobs baked at once")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-queued-jobs", options.maxQueuedJobs,
                 "Queued jobs before CreateBakeJob answers RESOURCE_EXHAUSTED")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--token-file", tokenFile,
                 "File holding the bearer token every call must carry (default: no auth)");
  auto* cert = app.add_option("--tls-cert", tlsCert, "PEM certificate chain (enables TLS)");
  auto* key = app.add_option("--tls-key", tlsKey, "PEM private key of --tls-cert");
  cert->needs(key);
  key->needs(cert);
  app.add_option("--port-file", portFile,
                 "Write the port listened on to this file once serving (for --listen host:0)");
  app.add_option("--log-level", logLevel, "trace, debug, info, warn, error or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}))
      ->capture_default_str();
  // Job limits (docs/job-format.md, "Errors"), reported by GetCapabilities; 0 means no limit.
  app.add_option("--max-probes", options.limits.maxProbes, "Probes per job")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-triangles", options.limits.maxTriangles, "Triangles per job")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-samples-per-probe", options.limits.maxSamplesPerProbe,
                 "settings.samplesPerProbe")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-sh-order", options.limits.maxShOrder, "settings.shOrder")
      ->check(CLI::Range(0, 8))
      ->capture_default_str();
  app.add_option("--max-depth", options.limits.maxDepth, "settings.maxDepth")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-lights", options.limits.maxLights, "Lights per scene")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-asset-bytes", options.limits.maxAssetBytes, "Bytes per mesh or map")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-environment-pixels", options.limits.maxEnvironmentPixels,
                 "Environment map pixels")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-texture-pixels", options.limits.maxTexturePixels,
                 "Pixels of a texture of a mesh file's materials")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--max-blob-bytes", options.maxBlobBytes, "Bytes per uploaded blob")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  int assetCheckSeconds = 600;
  app.add_option("--asset-check-timeout", assetCheckSeconds,
                 "Seconds a job's mesh and map files may take to import (in a child process, so "
                 "that a file that crashes or hangs the importer cannot take the server with it)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  int64_t assetCheckMemoryMb = 8192;
  app.add_option("--asset-check-memory-mb", assetCheckMemoryMb,
                 "Memory (MiB of heap and anonymous mappings) a job's files may take to import; "
                 "0: no limit")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  // The child side of that check (asset_check.h); not for people.
  std::string checkJobAssets, checkImportsOut;
  app.add_option("--check-job-assets", checkJobAssets)->group("");
  app.add_option("--check-imports-out", checkImportsOut)->group("");
  app.add_option("--checkpoint-interval", options.checkpointIntervalSeconds,
                 "Seconds between checkpoints of a running bake")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  double blobGraceHours = 24, gcIntervalMinutes = 60;
  app.add_option("--blob-grace-hours", blobGraceHours,
                 "Hours a blob no job refers to (a deleted job's volume or inputs, an upload no "
                 "job used) or an abandoned partial upload is kept after its last use (at "
                 "least 1/60: a minute)")
      ->check(CLI::Range(1.0 / 60, 1e6))
      ->capture_default_str();
  app.add_option("--gc-interval-minutes", gcIntervalMinutes,
                 "Minutes between collections of such files (0: never)")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str();
  int64_t diskReserveMb = options.diskReserveBytes >> 20;
  app.add_option("--disk-reserve-mb", diskReserveMb,
                 "MiB of disk held back (DATA/reserve) and given up when the disk is full, so "
                 "the job store can still record cancels, deletes and job ends (0: none)")
      ->check(CLI::Range(int64_t(0), int64_t(1) << 20))
      ->capture_default_str();
  // Where jobs bake (docs/cluster.md): in this process, or as arrays on a Slurm cluster.
  std::string backendName = "local";
  app.add_option("--backend", backendName,
                 "local: bake in this process; slurm: bake each job's shards as a Slurm array")
      ->check(CLI::IsMember({"local", "slurm"}))
      ->capture_default_str();
  srv::SlurmConfig slurm;
  app.add_option("--slurm-shared-dir", slurm.sharedDir,
                 "Shared folder (POSIX, the same absolute path on this machine and every node) "
                 "that holds each job's inputs, shards' volumes, progress and logs");
  app.add_option("--slurm-partition", slurm.partition, "Partition (default: the cluster's)");
  app.add_option("--slurm-shards", slurm.shards, "Shards per job")->check(CLI::NonNegativeNumber);
  app.add_option("--slurm-probes-per-shard", slurm.probesPerShard,
                 "Or: one shard per this many expected probes")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--slurm-retries", slurm.retries, "Submissions of a failed shard after its first")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--slurm-probebake", slurm.probebake,
                 "The probebake CLI the nodes run (default: the one beside this executable)");
  app.add_option("--slurm-cpus-per-task", slurm.cpusPerTask,
                 "sbatch --cpus-per-task of each shard (0: Slurm's default)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--slurm-sbatch-arg", slurm.sbatchArgs,
                 "More sbatch arguments, one per flag (e.g. --slurm-sbatch-arg=--time=4:00:00)");
  app.add_option("--slurm-bin-dir", slurm.binDir,
                 "Folder of sbatch, squeue and scancel (default: $PATH)");
  app.add_option("--slurm-poll-interval", slurm.pollSeconds, "Seconds between squeue polls")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--slurm-missing-part-grace", slurm.missingPartGraceSeconds,
                 "Seconds a shard's task may have ended before its volume shows in the shared "
                 "folder, before it counts as failed")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    int code = app.exit(e);
    return code == 0 ? 0 : kExitUsage;
  }
  if (!checkJobAssets.empty()) {
    // The server logs what matters about the check; the child stays quiet.
    probebake::SetLogLevel(spdlog::level::warn);
    // CPU time: the wall-clock limit's worth (the parent kills the child past it anyway; this
    // catches a child whose threads burn more CPU than wall time).
    const probebake::runtime::AssetCheckLimits resources{assetCheckMemoryMb << 20,
                                                         int64_t(assetCheckSeconds)};
    return srv::RunAssetCheckChild(checkJobAssets, checkImportsOut, dataDir, options.maxBlobBytes,
                                   options.limits, resources);
  }
  probebake::SetLogLevel(spdlog::level::from_str(logLevel));
  options.dataDir = dataDir;
  options.diskReserveBytes = diskReserveMb << 20;
  options.gc.grace = std::chrono::seconds(std::llround(blobGraceHours * 3600));
  options.gc.interval = std::chrono::seconds(std::llround(gcIntervalMinutes * 60));
  if (gcIntervalMinutes > 0 && options.gc.interval.count() == 0) {
    Logger("server")->error("--gc-interval-minutes: {} is under a second; use 0 for never",
                            gcIntervalMinutes);
    return kExitUsage;
  }
  const bool onSlurm = backendName == "slurm";
  // A job on the cluster holds a server thread that mostly waits for squeue.
  if (onSlurm && app.count("--max-concurrent-jobs") == 0) options.maxConcurrentJobs = 16;
  if (onSlurm && slurm.probebake.empty()) {
    std::error_code error;
    slurm.probebake =
        std::filesystem::read_symlink("/proc/self/exe", error).parent_path() / "probebake";
  }
  options.tokenFile = tokenFile;
  options.tlsCert = tlsCert;
  options.tlsKey = tlsKey;

  // Every thread (gRPC's, oneTBB's, the dispatcher) inherits this mask, so SIGTERM and SIGINT
  // reach only the sigwait below.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  // Every job's mesh files are imported in a child, this executable with these flags, and the job
  // is built from the child's imports (server/asset_check.h).
  std::vector<std::string> self(argv, argv + argc);
  self[0] = "/proc/self/exe";
  const auto checkTimeout = std::chrono::seconds(assetCheckSeconds);
  auto backend = [&self, checkTimeout, onSlurm,
                  &slurm](const srv::BackendContext& context) -> absl::StatusOr<srv::BakeBackend> {
    absl::StatusOr<srv::BakeBackend> made =
        onSlurm ? srv::SlurmBackend(context, slurm)
                : srv::ProductionBackend(context.blobs, context.limits);
    if (!made.ok()) return made;
    auto check =
        std::make_shared<const srv::AssetCheck>(self, context.blobs->tmpDir(), checkTimeout);
    // Both backends build as ProductionBackend does (BuildBakeJob over the blob store); this
    // build differs only in taking the meshes from the child.
    made->build = [check, blobs = context.blobs, limits = context.limits](
                      const probebake::v1::JobSpec& spec) -> absl::StatusOr<probebake::BakeJob> {
      absl::StatusOr<probebake::MeshImports> imports = check->Import(spec);
      if (!imports.ok()) return imports.status();
      const srv::BlobAssetSource assets(blobs, limits.maxAssetBytes);
      return probebake::BuildBakeJob(spec, assets, limits, {nullptr, &*imports});
    };
    return made;
  };
  auto server = srv::ProbebakeServer::Start(options, backend);
  if (!server.ok()) {
    Logger("server")->error("cannot start: {}", std::string(server.status().message()));
    return absl::IsInvalidArgument(server.status()) ? kExitUsage : kExitStartFailure;
  }
  if (!portFile.empty()) {
    absl::Status written =
        probebake::runtime::WriteFileAtomic(portFile, std::to_string((*server)->port()) + "\n");
    if (!written.ok()) {
      Logger("server")->error("--port-file: {}", std::string(written.message()));
      return kExitStartFailure;
    }
  }
  int signal = 0;
  sigwait(&signals, &signal);
  Logger("server")->info("{} received: shutting down", signal == SIGTERM ? "SIGTERM" : "SIGINT");
  (*server)->Shutdown();
  return 0;
}
