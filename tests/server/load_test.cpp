// A bounded load test of the service (the fake baker stands in for the tracer): many clients at
// once each submit jobs, watch them to the end and fetch their volumes, while one more streams a
// large upload. It checks that nothing is lost (every job succeeds once, every volume holds the
// values its job asked for, the upload reads back whole) and prints requests per second and
// latency percentiles per call; the figures are for docs/hardening.md, not asserted.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "probebake/job/digest.h"
#include "test_server.h"

namespace probebake::testing {
namespace {

using Clock = std::chrono::steady_clock;

struct Latencies {
  std::mutex mutex;
  std::vector<double> create, watch, fetch;
  void Add(std::vector<double>* to, Clock::time_point since) {
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - since).count();
    std::lock_guard lock(mutex);
    to->push_back(ms);
  }
};

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(q * double(v.size())))];
}

TEST(Load, ManyClientsSubmitWatchAndFetchWhileALargeUploadStreams) {
  constexpr int kClients = 32, kJobsPerClient = 6, kProbes = 8;
  TestServerOptions options;
  options.probeDelay = std::chrono::microseconds(500);
  options.maxConcurrentJobs = 2;
  options.maxQueuedJobs = kClients * kJobsPerClient;
  TestServer s(options);

  Latencies latencies;
  std::atomic<int> succeeded{0}, failures{0};
  std::mutex namesMutex;
  std::vector<std::string> names;
  const auto start = Clock::now();
  std::vector<std::thread> clients;
  for (int c = 0; c < kClients; ++c) {
    clients.emplace_back([&, c] {
      for (int j = 0; j < kJobsPerClient; ++j) {
        // A distinct seed per job: no result cache hits, every job bakes.
        const uint64_t seed = uint64_t(1000 + c * kJobsPerClient + j);
        auto t = Clock::now();
        const v1::BakeJob created = s.Create(SmallJob(kProbes, seed));
        latencies.Add(&latencies.create, t);
        {
          std::lock_guard lock(namesMutex);
          names.push_back(created.name());
        }
        t = Clock::now();
        const v1::BakeJob final = s.WaitFinal(created.name());
        latencies.Add(&latencies.watch, t);
        if (final.state() != v1::BakeJob::SUCCEEDED) {
          ++failures;
          ADD_FAILURE() << created.name() << " ended " << final.DebugString();
          continue;
        }
        t = Clock::now();
        const std::string volume = s.Download(final.result().volume());
        latencies.Add(&latencies.fetch, t);
        ExpectFakeVolume(volume, kProbes, seed);
        ++succeeded;
      }
    });
  }
  // The large upload, in 1 MiB messages, alongside.
  std::string big(size_t(64) << 20, '\0');
  for (size_t i = 0; i < big.size(); i += 4096) big[i] = char(i / 4096);
  const auto uploadStart = Clock::now();
  const v1::Digest digest = s.Upload(big);
  const double uploadSeconds = std::chrono::duration<double>(Clock::now() - uploadStart).count();
  for (std::thread& t : clients) t.join();
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  EXPECT_EQ(DigestOf(big).hash(), digest.hash());
  EXPECT_EQ(s.Download(digest), big);

  // Nothing lost or duplicated: one record per submitted job, each succeeded once.
  EXPECT_EQ(succeeded.load(), kClients * kJobsPerClient);
  EXPECT_EQ(failures.load(), 0);
  std::sort(names.begin(), names.end());
  EXPECT_EQ(std::unique(names.begin(), names.end()), names.end());
  EXPECT_EQ(s.bakeStats().bakes.load(), kClients * kJobsPerClient);
  EXPECT_EQ(s.Health(), 1);

  const size_t calls = latencies.create.size() + latencies.watch.size() + latencies.fetch.size();
  std::printf(
      "[measured] %d clients x %d jobs in %.2f s: %.0f calls/s (create, watch to the end, "
      "fetch); 64 MiB upload alongside at %.0f MiB/s\n",
      kClients, kJobsPerClient, seconds, double(calls) / seconds, 64 / uploadSeconds);
  for (const auto& [what, v] :
       {std::pair{"CreateBakeJob", &latencies.create}, std::pair{"fetch volume", &latencies.fetch},
        std::pair{"watch to the end", &latencies.watch}}) {
    std::printf("[measured] %s latency ms: p50 %.1f, p90 %.1f, p99 %.1f, max %.1f\n", what,
                Percentile(*v, 0.5), Percentile(*v, 0.9), Percentile(*v, 0.99),
                Percentile(*v, 1.0));
  }
}

}  // namespace
}  // namespace probebake::testing
