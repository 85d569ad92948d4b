#include "bench_reference.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <variant>

#include "bench_util.h"
#include "probebake/bake/bake.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"

namespace probebake::bench {
namespace {

// Cache file layout (little-endian, this machine's): the magic line, then the digest line, then
// int64 probes, int32 order, samples (int64), maxDepth, batches (int32), seed (uint64), seconds
// (double), then per probe: active (uint8), and when active the RGB radiance and std error of
// every coefficient (double) and the relative std error (double).
constexpr char kMagic[] = "probebake-bench-reference 2\n";

template <typename T>
void Put(std::string* out, const T& value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

class Reader {
 public:
  explicit Reader(const std::string& bytes) : bytes_(bytes) {}
  template <typename T>
  bool Get(T* value) {
    if (pos_ + sizeof(T) > bytes_.size()) return false;
    std::memcpy(value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool Line(std::string* line) {
    const size_t end = bytes_.find('\n', pos_);
    if (end == std::string::npos) return false;
    *line = bytes_.substr(pos_, end - pos_ + 1);
    pos_ = end + 1;
    return true;
  }
  bool AtEnd() const { return pos_ == bytes_.size(); }

 private:
  const std::string& bytes_;
  size_t pos_ = 0;
};

std::string Serialise(const Reference& r) {
  std::string out = kMagic;
  out += r.jobDigest + "\n";
  Put(&out, int64_t(r.active.size()));
  Put(&out, int32_t(r.order));
  Put(&out, int64_t(r.samplesPerProbe));
  Put(&out, int32_t(r.maxDepth));
  Put(&out, int32_t(r.batches));
  Put(&out, uint64_t(r.seed));
  Put(&out, r.bakeSeconds);
  const int coeffs = ShCoeffCount(r.order);
  for (size_t p = 0; p < r.active.size(); ++p) {
    Put(&out, uint8_t(r.active[p]));
    if (!r.active[p]) continue;
    for (int c = 0; c < coeffs; ++c)
      for (int ch = 0; ch < 3; ++ch) Put(&out, r.radiance[p][c][ch]);
    for (int c = 0; c < coeffs; ++c)
      for (int ch = 0; ch < 3; ++ch) Put(&out, r.stdError[p][c][ch]);
    Put(&out, r.relStdError[p]);
    Put(&out, r.relStdErrorL0[p]);
  }
  return out;
}

absl::StatusOr<Reference> Deserialise(const std::string& bytes, const std::string& digest) {
  Reader in(bytes);
  std::string line;
  if (!in.Line(&line) || line != kMagic) return absl::DataLossError("bad magic");
  if (!in.Line(&line) || line != digest + "\n") return absl::DataLossError("digest mismatch");
  Reference r;
  r.jobDigest = digest;
  int64_t probes = 0;
  int32_t order = 0, depth = 0, batches = 0;
  int64_t samples = 0;
  uint64_t seed = 0;
  if (!in.Get(&probes) || !in.Get(&order) || !in.Get(&samples) || !in.Get(&depth) ||
      !in.Get(&batches) || !in.Get(&seed) || !in.Get(&r.bakeSeconds) || probes < 0 || order < 0 ||
      order > kMaxShOrder)
    return absl::DataLossError("bad header");
  r.order = order;
  r.samplesPerProbe = samples;
  r.maxDepth = depth;
  r.batches = batches;
  r.seed = seed;
  const int coeffs = ShCoeffCount(order);
  r.active.assign(size_t(probes), 0);
  r.radiance.assign(size_t(probes), {});
  r.stdError.assign(size_t(probes), {});
  r.relStdError.assign(size_t(probes), 0.0);
  r.relStdErrorL0.assign(size_t(probes), 0.0);
  for (int64_t p = 0; p < probes; ++p) {
    uint8_t active = 0;
    if (!in.Get(&active)) return absl::DataLossError("truncated");
    r.active[p] = active;
    if (!active) continue;
    r.radiance[p].resize(coeffs);
    r.stdError[p].resize(coeffs);
    for (int c = 0; c < coeffs; ++c)
      for (int ch = 0; ch < 3; ++ch)
        if (!in.Get(&r.radiance[p][c][ch])) return absl::DataLossError("truncated");
    for (int c = 0; c < coeffs; ++c)
      for (int ch = 0; ch < 3; ++ch)
        if (!in.Get(&r.stdError[p][c][ch])) return absl::DataLossError("truncated");
    if (!in.Get(&r.relStdError[p]) || !in.Get(&r.relStdErrorL0[p]))
      return absl::DataLossError("truncated");
  }
  if (!in.AtEnd()) return absl::DataLossError("trailing bytes");
  r.fromCache = true;
  return r;
}

}  // namespace

namespace {

constexpr double kPi = std::numbers::pi;

double Legendre(int l, double x) {
  if (l == 0) return 1;
  double p0 = 1, p1 = x;
  for (int k = 2; k <= l; ++k) {
    const double p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
    p0 = p1;
    p1 = p2;
  }
  return p1;
}

// SH of the indicator of the cap {w : w . axis >= cosMax} (Funk-Hecke):
// c_lm = 2 pi (int_{cosMax}^1 P_l(t) dt) Y_lm(axis), with
// int_a^1 P_l = (P_{l-1}(a) - P_{l+1}(a)) / (2l + 1) for l >= 1 and 1 - a for l = 0.
std::vector<double> CapProjection(int order, const Vec3d& axis, double cosMax) {
  std::vector<double> y(ShCoeffCount(order)), out(ShCoeffCount(order));
  EvalShBasis(order, axis, y.data());
  for (int l = 0; l <= order; ++l) {
    const double integral =
        l == 0 ? 1 - cosMax : (Legendre(l - 1, cosMax) - Legendre(l + 1, cosMax)) / (2 * l + 1);
    for (int m = -l; m <= l; ++m) out[ShIndex(l, m)] = 2 * kPi * integral * y[ShIndex(l, m)];
  }
  return out;
}

}  // namespace

absl::StatusOr<std::vector<Vec3d>> AnalyticSkySphereProjection(const Scene& scene, double groundZ,
                                                               const Vec3d& p, int order) {
  if (scene.environment.kind != Environment::Kind::kUniform)
    return absl::FailedPreconditionError("analytic reference: needs a uniform environment");
  for (const Material& m : scene.materials)
    if (MaxComponent(m.albedo) != 0 || MaxComponent(m.emission) != 0)
      return absl::FailedPreconditionError("analytic reference: every material must be black");
  if (!(p.z > groundZ))
    return absl::FailedPreconditionError("analytic reference: probe below the ground");
  const Vec3d sky = scene.environment.radiance;
  std::vector<Vec3d> out(ShCoeffCount(order));
  const std::vector<double> upper = CapProjection(order, {0, 0, 1}, 0);
  for (size_t i = 0; i < out.size(); ++i) out[i] = sky * upper[i];
  for (const Light& light : scene.lights) {
    const auto* sphere = std::get_if<SphereLight>(&light);
    if (!sphere) return absl::FailedPreconditionError("analytic reference: sphere lights only");
    const Vec3d v = sphere->center - p;
    const double d = Length(v);
    if (!(d > sphere->radius))
      return absl::FailedPreconditionError("analytic reference: probe inside a sphere light");
    const Vec3d axis = v / d;
    const double sinHalf = sphere->radius / d;
    const double cosMax = std::sqrt((1 - sinHalf) * (1 + sinHalf));
    // The cap must lie wholly above the horizon: elevation of its axis > its half-angle.
    if (!(std::asin(std::clamp(axis.z, -1.0, 1.0)) > std::asin(sinHalf)))
      return absl::FailedPreconditionError("analytic reference: sphere light below the horizon");
    const std::vector<double> cap = CapProjection(order, axis, cosMax);
    for (size_t i = 0; i < out.size(); ++i) out[i] += (sphere->radiance - sky) * cap[i];
  }
  return out;
}

absl::StatusOr<Reference> AnalyticReference(const BakeJob& job, int order) {
  Reference r;
  r.exact = true;
  r.order = order;
  r.jobDigest = job.jobDigest;
  const int64_t probes = job.grid.ProbeCount();
  r.active.assign(size_t(probes), 1);
  r.radiance.resize(size_t(probes));
  r.stdError.assign(size_t(probes), std::vector<Vec3d>(ShCoeffCount(order)));
  r.relStdError.assign(size_t(probes), 0.0);
  r.relStdErrorL0.assign(size_t(probes), 0.0);
  // The ground of the sky_sphere scene is its one mesh, a plane at constant height.
  if (job.scene.meshes.size() != 1)
    return absl::FailedPreconditionError("analytic reference: expects one ground mesh");
  const double groundZ = job.scene.meshes[0].positions.at(0).z;
  for (const Vec3d& v : job.scene.meshes[0].positions)
    if (v.z != groundZ) return absl::FailedPreconditionError("analytic reference: ground not flat");
  for (int64_t p = 0; p < probes; ++p) {
    int i, j, k;
    job.grid.Coords(p, &i, &j, &k);
    PB_ASSIGN_OR_RETURN(r.radiance[p], AnalyticSkySphereProjection(
                                           job.scene, groundZ, job.grid.Position(i, j, k), order));
  }
  return r;
}

absl::StatusOr<Reference> BakedReference(const BenchScene& scene, const v1::BakeSettings& settings,
                                         const std::string& cacheDir, int threads) {
  auto log = Logger("bench");
  PB_ASSIGN_OR_RETURN(const BakeJob job, BuildSceneJob(scene, settings));
  const std::string path = cacheDir + "/reference-" + job.jobDigest + ".bin";
  if (absl::StatusOr<std::string> bytes = ReadFileBytes(path); bytes.ok()) {
    absl::StatusOr<Reference> cached = Deserialise(*bytes, job.jobDigest);
    if (cached.ok()) {
      log->info("{}: reference from cache {}", scene.name, path);
      return cached;
    }
    log->warn("{}: ignoring unreadable cached reference {}: {}", scene.name, path,
              std::string(cached.status().message()));
  }

  log->info(
      "{}: baking the reference ({} samples/probe, order {}, depth {}, {} batches); cached "
      "as {}",
      scene.name, job.settings.samplesPerProbe, job.settings.shOrder, job.settings.maxDepth,
      job.settings.batches, path);
  BakeOptions options;
  options.threads = threads;
  options.coefficientErrors = true;
  options.progressIntervalSeconds = 15;
  options.progress = [&](const BakeProgress& p) {
    log->info("{}: reference {}/{} probes, {:.0f} s elapsed, ETA {:.0f} s", scene.name,
              p.probesDone, p.probesTotal, p.elapsedSeconds, p.etaSeconds);
  };
  const double start = WallSeconds();
  PB_ASSIGN_OR_RETURN(const ProbeVolume volume, Bake(job, options));

  Reference r;
  r.order = volume.shOrder;
  r.samplesPerProbe = job.settings.samplesPerProbe;
  r.maxDepth = job.settings.maxDepth;
  r.batches = job.settings.batches;
  r.seed = job.settings.seed;
  r.jobDigest = job.jobDigest;
  r.bakeSeconds = WallSeconds() - start;
  const int64_t probes = volume.grid.ProbeCount();
  const int coeffs = volume.CoeffCount();
  r.active.assign(size_t(probes), 0);
  r.radiance.assign(size_t(probes), {});
  r.stdError.assign(size_t(probes), {});
  r.relStdError.assign(size_t(probes), 0.0);
  r.relStdErrorL0.assign(size_t(probes), 0.0);
  for (int64_t p = 0; p < probes; ++p) {
    if (!volume.active[p] || volume.validity[p] == 0.0f) continue;
    r.active[p] = 1;
    r.radiance[p].resize(coeffs);
    r.stdError[p].resize(coeffs);
    for (int c = 0; c < coeffs; ++c) {
      for (int ch = 0; ch < 3; ++ch) {
        r.radiance[p][c][ch] = volume.radiance[c][3 * p + ch];
        r.stdError[p][c][ch] = volume.radianceStdError[c][3 * p + ch];
      }
    }
    r.relStdError[p] = volume.stdError[p];
    r.relStdErrorL0[p] = volume.stdErrorL0[p];
  }
  PB_RETURN_IF_ERROR(WriteFileAtomic(path, Serialise(r)));
  log->info("{}: reference baked in {:.1f} s", scene.name, r.bakeSeconds);
  return r;
}

double ReferenceDifference(const Reference& a, const Reference& b, int order) {
  double sum = 0;
  int n = 0;
  const int coeffs = ShCoeffCount(order);
  std::vector<double> band(coeffs);
  for (int l = 0; l <= order; ++l)
    for (int m = -l; m <= l; ++m) band[ShIndex(l, m)] = IrradianceBandFactor(l);
  for (size_t p = 0; p < a.active.size(); ++p) {
    if (!a.active[p] || !b.active[p]) continue;
    double d2 = 0, r2 = 0;
    for (int c = 0; c < coeffs; ++c) {
      const Vec3d d = (a.radiance[p][c] - b.radiance[p][c]) * band[c];
      const Vec3d r = b.radiance[p][c] * band[c];
      d2 += Dot(d, d);
      r2 += Dot(r, r);
    }
    if (r2 > 0) {
      sum += std::sqrt(d2 / r2);
      ++n;
    }
  }
  return n ? sum / n : -1;
}

std::string ReferenceText(const Reference& r, int64_t ladderMax) {
  if (r.exact) return "closed form (exact SH projection, Funk-Hecke)";
  double irr = 0, se = 0, seL0 = 0;
  int n = 0;
  for (size_t p = 0; p < r.active.size(); ++p) {
    if (!r.active[p]) continue;
    double pred = 0, norm = 0;
    for (int l = 0; l <= 2; ++l) {
      const double a = IrradianceBandFactor(l);
      for (int m = -l; m <= l; ++m) {
        const int c = ShIndex(l, m);
        pred += a * a * Dot(r.stdError[p][c], r.stdError[p][c]);
        norm += a * a * Dot(r.radiance[p][c], r.radiance[p][c]);
      }
    }
    if (norm > 0) {
      irr += std::sqrt(pred / norm);
      se += r.relStdError[p];
      seL0 += r.relStdErrorL0[p];
      ++n;
    }
  }
  const std::string origin =
      r.fromCache ? "read from the cache" : Format("baked in %.0f s", r.bakeSeconds);
  return Format(
      "bake of %lld samples/probe (%lldx the largest ladder count), order %d, depth %d, %d "
      "batches, seed %#llx, its own expected error: irradiance %.3g%% (RGB), std_error %.3g%%, "
      "std_error_l0 %.3g%% (means over probes); job digest %.12s..., %s",
      (long long)r.samplesPerProbe, (long long)(r.samplesPerProbe / ladderMax), r.order, r.maxDepth,
      r.batches, (unsigned long long)r.seed, 100 * irr / std::max(n, 1), 100 * se / std::max(n, 1),
      100 * seL0 / std::max(n, 1), r.jobDigest.c_str(), origin.c_str());
}

}  // namespace probebake::bench
