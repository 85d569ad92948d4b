// probebake_fake_server: probebake-server with the fake baker (fake_backend.h), for process-level
// tests (SIGKILL mid-bake, SIGTERM drain, data folder lock) that must not depend on the tracer.
// Same flags as probebake-server where they matter, plus --probe-delay-us.
#include <signal.h>

#include <CLI/CLI.hpp>

#include "fake_backend.h"
#include "probebake/base/log.h"
#include "runtime/files.h"
#include "server/server.h"

int main(int argc, char** argv) {
  namespace srv = probebake::server;
  srv::ServerOptions options;
  std::string dataDir, portFile, tokenFile;
  int64_t probeDelayUs = 2000;
  CLI::App app{"probebake-server with a fake baker, for tests"};
  app.add_option("--listen", options.listen);
  app.add_option("--data-dir", dataDir)->required();
  app.add_option("--port-file", portFile);
  app.add_option("--token-file", tokenFile);
  app.add_option("--max-concurrent-jobs", options.maxConcurrentJobs);
  app.add_option("--max-queued-jobs", options.maxQueuedJobs);
  app.add_option("--checkpoint-interval", options.checkpointIntervalSeconds);
  app.add_option("--probe-delay-us", probeDelayUs);
  CLI11_PARSE(app, argc, argv);
  options.dataDir = dataDir;
  options.tokenFile = tokenFile;
  options.threadsPerJob = 1;

  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  probebake::testing::FakeBakeStats stats;
  auto delay = std::chrono::microseconds(probeDelayUs);
  auto server = srv::ProbebakeServer::Start(
      options, [&](const srv::BackendContext& context) -> absl::StatusOr<srv::BakeBackend> {
        return probebake::testing::FakeBackend(context.blobs, context.limits, delay, &stats);
      });
  if (!server.ok()) {
    probebake::Logger("server")->error("cannot start: {}", std::string(server.status().message()));
    return 1;
  }
  if (!portFile.empty() &&
      !probebake::runtime::WriteFileAtomic(portFile, std::to_string((*server)->port()) + "\n").ok())
    return 1;
  int signal = 0;
  sigwait(&signals, &signal);
  (*server)->Shutdown();
  probebake::Logger("server")->info("fake baker: {} bakes, {} resumed, {} probes, max {} at once",
                                    stats.bakes.load(), stats.resumed.load(),
                                    stats.probesBaked.load(), stats.maxActivePerJob);
  return 0;
}
