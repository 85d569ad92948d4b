#include "server/checkpoint.h"

#include <algorithm>
#include <cstring>
#include <type_traits>

#include "absl/strings/str_cat.h"
#include "probebake/base/byte_codec.h"
#include "probebake/base/status.h"
#include "probebake/job/digest.h"
#include "runtime/files.h"

namespace probebake::server {
namespace {

constexpr char kMagic[8] = {'P', 'B', 'C', 'K', 'P', 'T', '0', '5'};
// 04: no offsets, visibility moments, filled flags or window parameters.
constexpr char kMagic04[8] = {'P', 'B', 'C', 'K', 'P', 'T', '0', '4'};
// The formats before the L0 standard errors (03) and before BakeWork (02).
constexpr char kMagic03[8] = {'P', 'B', 'C', 'K', 'P', 'T', '0', '3'};
constexpr char kMagic02[8] = {'P', 'B', 'C', 'K', 'P', 'T', '0', '2'};
constexpr size_t kHashHexBytes = 64;

using Writer = ByteWriter;
using Reader = ByteReader;

void WriteVolume(const ProbeVolume& v, Writer* w) {
  w->Pod(v.grid.origin);
  w->Pod(v.grid.spacing);
  for (int a = 0; a < 3; ++a) w->Pod(int32_t(v.grid.counts[a]));
  w->Pod(int32_t(v.grid.placement));
  w->Pod(v.grid.surfaceDistance);
  w->Pod(int32_t(v.shOrder));
  w->Vector(v.active);
  for (const auto* planes : {&v.radiance, &v.irradiance, &v.radianceStdError}) {
    w->Pod(uint64_t(planes->size()));
    for (const std::vector<float>& plane : *planes) w->Vector(plane);
  }
  w->Vector(v.validity);
  w->Vector(v.stdError);
  w->Vector(v.sampleCount);
  w->String(v.window);
  w->Pod(v.stats.wallSeconds);
  w->Pod(int32_t(v.stats.threads));
  w->Pod(v.stats.probes);
  w->Pod(v.stats.samples);
  w->Pod(v.stats.rays);
  w->Pod(v.stats.invalidProbes);
}

bool ReadVolume(Reader* r, ProbeVolume* v) {
  int32_t counts[3], placement, shOrder, threads;
  if (!r->Pod(&v->grid.origin) || !r->Pod(&v->grid.spacing)) return false;
  for (int a = 0; a < 3; ++a) {
    if (!r->Pod(&counts[a]) || counts[a] < 1) return false;
    v->grid.counts[a] = counts[a];
  }
  if (!r->Pod(&placement) || placement < 0 || placement > int32_t(Placement::kNearSurfaces))
    return false;
  v->grid.placement = Placement(placement);
  if (!r->Pod(&v->grid.surfaceDistance) || !r->Pod(&shOrder) || shOrder < 0) return false;
  v->shOrder = shOrder;
  if (!r->Vector(&v->active)) return false;
  for (auto* planes : {&v->radiance, &v->irradiance, &v->radianceStdError}) {
    uint64_t n;
    if (!r->Pod(&n) || n > 1024) return false;
    planes->resize(size_t(n));
    for (std::vector<float>& plane : *planes)
      if (!r->Vector(&plane)) return false;
  }
  if (!r->Vector(&v->validity) || !r->Vector(&v->stdError) || !r->Vector(&v->sampleCount) ||
      !r->String(&v->window))
    return false;
  if (!r->Pod(&v->stats.wallSeconds) || !r->Pod(&threads) || !r->Pod(&v->stats.probes) ||
      !r->Pod(&v->stats.samples) || !r->Pod(&v->stats.rays) || !r->Pod(&v->stats.invalidProbes))
    return false;
  v->stats.threads = threads;
  return true;
}

}  // namespace

std::filesystem::path CheckpointFilePath(const std::filesystem::path& dataDir,
                                         std::string_view jobName) {
  std::string_view id = jobName.substr(std::min(jobName.find('/') + 1, jobName.size()));
  return dataDir / "checkpoints" / (std::string(id) + ".ckpt");
}

int64_t Checkpoint::DoneCount() const {
  int64_t n = 0;
  for (uint8_t d : done) n += d != 0;
  return n;
}

absl::Status WriteCheckpoint(const std::filesystem::path& path, const std::string& jobDigest,
                             const ProbeVolume& volume, const std::vector<uint8_t>& done,
                             const BakeWork& work) {
  Writer w;
  w.bytes().append(kMagic, sizeof(kMagic));
  w.String(jobDigest);
  WriteVolume(volume, &w);
  w.Vector(done);
  w.Pod(work.wallSeconds);
  w.Pod(work.samples);
  w.Pod(work.rays);
  w.Vector(volume.stdErrorL0);
  // 05: the per-probe planes of relocation, visibility, dilation, the automatic window and the
  // sky transfer, which a resumed bake copies from the checkpoint with the radiance of finished
  // probes.
  w.Vector(volume.offset);
  w.Vector(volume.filled);
  w.Vector(volume.autoWindowT);
  w.Pod(uint64_t(volume.visibility.size()));
  for (const std::vector<float>& plane : volume.visibility) w.Vector(plane);
  w.Pod(int32_t(volume.skyTransferOrder));
  w.Pod(uint64_t(volume.skyTransfer.size()));
  for (const std::vector<float>& plane : volume.skyTransfer) w.Vector(plane);
  std::string hash = Sha256Hex(w.bytes());
  w.bytes().append(hash);
  return runtime::WriteFileAtomic(path, w.bytes());
}

namespace {

// `expectedJobDigest` null: any.
absl::StatusOr<Checkpoint> Read(const std::filesystem::path& path,
                                const std::string* expectedJobDigest) {
  PB_ASSIGN_OR_RETURN(std::string bytes, runtime::ReadWholeFile(path));
  auto corrupt = [&](std::string_view why) {
    return absl::DataLossError(absl::StrCat("checkpoint ", path.string(), ": ", std::string(why)));
  };
  if (bytes.size() < sizeof(kMagic) + kHashHexBytes) return corrupt("not a probebake checkpoint");
  const bool current = std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) == 0;
  const bool hasL0 = current || std::memcmp(bytes.data(), kMagic04, sizeof(kMagic04)) == 0;
  const bool hasWork = hasL0 || std::memcmp(bytes.data(), kMagic03, sizeof(kMagic03)) == 0;
  if (!hasWork && std::memcmp(bytes.data(), kMagic02, sizeof(kMagic02)) != 0)
    return corrupt("not a probebake checkpoint");
  std::string_view body(bytes.data(), bytes.size() - kHashHexBytes);
  if (Sha256Hex(body) != std::string_view(bytes).substr(body.size()))
    return corrupt("checksum mismatch (torn or corrupt file)");
  Reader r(body.substr(sizeof(kMagic)));
  Checkpoint c;
  if (!r.String(&c.jobDigest) || !ReadVolume(&r, &c.volume) || !r.Vector(&c.done))
    return corrupt("malformed contents");
  if (hasWork && (!r.Pod(&c.work.wallSeconds) || !r.Pod(&c.work.samples) || !r.Pod(&c.work.rays)))
    return corrupt("malformed contents");
  if (!hasL0) {
    c.volume.stdErrorL0 = c.volume.stdError;  // before 04 std_error was the L0 figure
  } else if (!r.Vector(&c.volume.stdErrorL0)) {
    return corrupt("malformed contents");
  }
  if (current) {
    uint64_t planes = 0;
    if (!r.Vector(&c.volume.offset) || !r.Vector(&c.volume.filled) ||
        !r.Vector(&c.volume.autoWindowT) || !r.Pod(&planes) || planes > 4096)
      return corrupt("malformed contents");
    c.volume.visibility.resize(size_t(planes));
    for (std::vector<float>& plane : c.volume.visibility)
      if (!r.Vector(&plane)) return corrupt("malformed contents");
    int32_t skyOrder = 0;
    if (!r.Pod(&skyOrder) || skyOrder < 0 || skyOrder > 64 || !r.Pod(&planes) || planes > 1 << 20)
      return corrupt("malformed contents");
    c.volume.skyTransferOrder = skyOrder;
    c.volume.skyTransfer.resize(size_t(planes));
    for (std::vector<float>& plane : c.volume.skyTransfer)
      if (!r.Vector(&plane)) return corrupt("malformed contents");
  }
  if (!r.AtEnd()) return corrupt("malformed contents");
  if (expectedJobDigest && c.jobDigest != *expectedJobDigest)
    return corrupt(absl::StrCat("made for job digest ", c.jobDigest, ", not ", *expectedJobDigest));
  if (int64_t(c.done.size()) != c.volume.grid.ProbeCount())
    return corrupt("done flags do not match the grid");
  return c;
}

}  // namespace

absl::StatusOr<Checkpoint> ReadCheckpoint(const std::filesystem::path& path,
                                          const std::string& expectedJobDigest) {
  return Read(path, &expectedJobDigest);
}

absl::StatusOr<Checkpoint> ReadCheckpointOfAnyJob(const std::filesystem::path& path) {
  return Read(path, nullptr);
}

}  // namespace probebake::server
