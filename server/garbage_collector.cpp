#include "server/garbage_collector.h"

#include <algorithm>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include "absl/strings/str_format.h"
#include "probebake/base/check.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "server/blob_store.h"
#include "server/job_store.h"

namespace probebake::server {
namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;

// Every Digest inside `message`, found by reflection so that a blob field added to the job spec
// later is counted without a change here.
void CollectDigests(const Message& message, std::set<std::string>* hashes) {
  if (message.GetDescriptor() == v1::Digest::descriptor()) {
    const auto& digest = static_cast<const v1::Digest&>(message);
    if (!digest.hash().empty()) hashes->insert(digest.hash());
    return;
  }
  const google::protobuf::Reflection* reflection = message.GetReflection();
  std::vector<const FieldDescriptor*> fields;
  reflection->ListFields(message, &fields);
  for (const FieldDescriptor* field : fields) {
    if (field->cpp_type() != FieldDescriptor::CPPTYPE_MESSAGE) continue;
    if (field->is_repeated()) {
      for (int i = 0; i < reflection->FieldSize(message, field); ++i)
        CollectDigests(reflection->GetRepeatedMessage(message, field, i), hashes);
    } else {
      CollectDigests(reflection->GetMessage(message, field), hashes);
    }
  }
}

std::string Megabytes(int64_t bytes) {
  return absl::StrFormat("%.1f MB", double(bytes) / 1e6);
}

}  // namespace

std::set<std::string> BlobsOfSpec(const v1::JobSpec& spec) {
  std::set<std::string> hashes;
  CollectDigests(spec, &hashes);
  return hashes;
}

GarbageCollector::GarbageCollector(JobStore* jobs, BlobStore* blobs, PendingBlobs pending,
                                   GcConfig config)
    : jobs_(jobs), blobs_(blobs), pending_(std::move(pending)), config_(config) {
  PB_CHECK(config_.grace >= GcConfig::kMinGrace);
}

GarbageCollector::~GarbageCollector() {
  Stop();
}

void GarbageCollector::Start() {
  if (config_.interval.count() <= 0) {
    Logger("gc")->info("periodic collection off; unreferenced files are kept");
    return;
  }
  if (thread_.joinable()) return;
  Logger("gc")->info("collecting every {} s the files no job refers to and unused for {} s",
                     config_.interval.count(), config_.grace.count());
  thread_ = std::thread([this] { Loop(); });
}

void GarbageCollector::Stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void GarbageCollector::Loop() {
  std::unique_lock lock(mutex_);
  while (!wake_.wait_for(lock, config_.interval, [&] { return stopping_; })) {
    lock.unlock();
    if (absl::StatusOr<GcReport> report = CollectNow(); !report.ok())
      Logger("gc")->warn("collection skipped: {}", std::string(report.status().message()));
    if (after_) after_();
    lock.lock();
  }
}

absl::StatusOr<GcReport> GarbageCollector::CollectNow() {
  std::lock_guard collecting(collecting_);
  GcReport report;
  // In this order: the blobs pending a reference, then the references. A volume whose job's end
  // is stored in between is among the references; one imported after the first step is newer
  // than `since`, as is every blob stored or touched from then on (a new job's inputs, a cache
  // hit), so none of them is removed.
  std::filesystem::file_time_type since;
  std::set<std::string> live = pending_(&since);
  PB_RETURN_IF_ERROR(jobs_->ForEachJob([&](const v1::BakeJob& record, const v1::JobSpec& spec) {
    live.merge(BlobsOfSpec(spec));
    if (record.has_result() && !record.result().volume().hash().empty())
      live.insert(record.result().volume().hash());
  }));
  report.liveBlobs = int64_t(live.size());
  const BlobStore::Collected collected = blobs_->Collect(
      live, std::min(since, std::filesystem::file_time_type::clock::now() - config_.grace));
  report.blobs = collected.blobs;
  report.blobBytes = collected.blobBytes;
  report.partials = collected.partials;
  report.partialBytes = collected.partialBytes;

  // Cache entries whose volume is gone would only be dropped at their next hit.
  PB_ASSIGN_OR_RETURN(auto cached, jobs_->ListCached());
  for (const auto& [jobDigest, result] : cached) {
    if (blobs_->Contains(result.volume())) continue;
    // Only if unchanged: a bake of the same job may have stored a new volume meanwhile.
    bool dropped = false;
    PB_RETURN_IF_ERROR(
        jobs_->Transaction([&, &jobDigest = jobDigest, &result = result]() -> absl::Status {
          PB_ASSIGN_OR_RETURN(std::optional<v1::BakeJobResult> now, jobs_->GetCached(jobDigest));
          if (!now || now->volume().hash() != result.volume().hash()) return absl::OkStatus();
          dropped = true;
          return jobs_->DeleteCached(jobDigest);
        }));
    report.cacheEntries += dropped ? 1 : 0;
  }

  auto log = Logger("gc");
  const auto level = report.blobs + report.partials + report.cacheEntries > 0
                         ? spdlog::level::info
                         : spdlog::level::debug;
  log->log(
      level,
      "removed {} unreferenced blobs ({}), {} abandoned partial uploads ({}) and {} result-cache "
      "entries; {} blobs referenced by jobs",
      report.blobs, Megabytes(report.blobBytes), report.partials, Megabytes(report.partialBytes),
      report.cacheEntries, report.liveBlobs);
  return report;
}

}  // namespace probebake::server
