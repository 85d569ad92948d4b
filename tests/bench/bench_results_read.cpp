// ReadResultsJson: results.json (written by Json() in bench_report.cpp) back into BenchResults, so
// the documents' generated blocks can be rebuilt from the committed results without a bench run
// (probebake-bench --docs-only). Keys here must follow that writer.
#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <cmath>
#include <string>

#include "bench_report.h"
#include "bench_util.h"
#include "probebake/base/status.h"

namespace probebake::bench {
namespace {

using google::protobuf::ListValue;
using google::protobuf::Struct;
using google::protobuf::Value;

// Reads the keys of one JSON object; the first missing or mistyped key is kept as the error.
class Fields {
 public:
  Fields(const Struct& object, std::string path, absl::Status* error)
      : object_(object), path_(std::move(path)), error_(error) {}

  const Value* Get(const char* key, Value::KindCase kind) {
    const auto it = object_.fields().find(key);
    if (it == object_.fields().end() ||
        (it->second.kind_case() != kind && it->second.kind_case() != Value::kNullValue)) {
      Fail(key, it == object_.fields().end() ? "missing" : "of the wrong type");
      return nullptr;
    }
    return &it->second;
  }
  // JSON null is how the writer prints a non-finite number.
  double Number(const char* key) {
    const Value* v = Get(key, Value::kNumberValue);
    return v && v->kind_case() == Value::kNumberValue ? v->number_value() : NAN;
  }
  int64_t Integer(const char* key) {
    const double x = Number(key);
    return std::isfinite(x) ? int64_t(std::llround(x)) : 0;
  }
  std::string String(const char* key) {
    const Value* v = Get(key, Value::kStringValue);
    return v && v->kind_case() == Value::kStringValue ? v->string_value() : "";
  }
  bool Bool(const char* key) {
    const Value* v = Get(key, Value::kBoolValue);
    return v && v->kind_case() == Value::kBoolValue && v->bool_value();
  }
  const ListValue& List(const char* key) {
    static const ListValue kEmpty;
    const Value* v = Get(key, Value::kListValue);
    return v && v->kind_case() == Value::kListValue ? v->list_value() : kEmpty;
  }
  std::vector<double> Numbers(const char* key) {
    std::vector<double> out;
    for (const Value& v : List(key).values()) out.push_back(v.number_value());
    return out;
  }
  const Struct& Object(const char* key) {
    static const Struct kEmpty;
    const Value* v = Get(key, Value::kStructValue);
    return v && v->kind_case() == Value::kStructValue ? v->struct_value() : kEmpty;
  }
  std::string Path(const std::string& key) const { return path_ + "." + key; }
  // Whether the object has `key` (for keys that older results lack).
  bool Has(const char* key) const { return object_.fields().contains(key); }

 private:
  void Fail(const char* key, const char* reason) {
    if (error_->ok()) *error_ = absl::InvalidArgumentError(Path(key) + ": " + reason);
  }

  const Struct& object_;
  std::string path_;
  absl::Status* error_;
};

// The objects of list `key`, each with its path for errors.
template <typename F>
void ForEachObject(Fields& parent, const char* key, absl::Status* error, F&& read) {
  const ListValue& list = parent.List(key);
  for (int i = 0; i < list.values_size(); ++i) {
    const std::string path = parent.Path(key) + "[" + std::to_string(i) + "]";
    if (list.values(i).kind_case() != Value::kStructValue) {
      if (error->ok()) *error = absl::InvalidArgumentError(path + ": not an object");
      return;
    }
    Fields item(list.values(i).struct_value(), path, error);
    read(item);
  }
}

}  // namespace

absl::StatusOr<BenchResults> ReadResultsJson(const std::string& path) {
  PB_ASSIGN_OR_RETURN(const std::string text, ReadFileBytes(path));
  Struct root;
  if (const auto parsed = google::protobuf::util::JsonStringToMessage(text, &root); !parsed.ok())
    return absl::InvalidArgumentError(path + ": " + std::string(parsed.message()));
  absl::Status error;
  Fields f(root, path, &error);
  BenchResults r;
  r.date = f.String("date");
  r.host = f.String("host");
  r.generator = f.String("generator");
  r.quick = f.Bool("quick");
  r.hardwareThreads = int(f.Integer("hardwareThreads"));
  r.loadStart = f.Number("loadStart");
  r.loadEnd = f.Number("loadEnd");
  r.totalSeconds = f.Number("totalSeconds");
  r.presetText = f.String("presets");
  for (double n : f.Numbers("ladder")) r.ladder.push_back(int64_t(n));
  ForEachObject(f, "scenes", &error, [&](Fields& s) {
    SceneInfo scene;
    scene.name = s.String("name");
    scene.description = s.String("description");
    scene.triangles = s.Integer("triangles");
    scene.gridProbes = s.Integer("gridProbes");
    scene.bakedProbes = s.Integer("bakedProbes");
    scene.referenceText = s.String("reference");
    scene.depthBiasIrradiance = s.Number("depthBiasIrradiance");
    r.scenes.push_back(scene);
  });
  ForEachObject(f, "bakes", &error, [&](Fields& b) {
    BakeRow row;
    row.scene = b.String("scene");
    row.config = b.String("config");
    row.label = row.config;
    row.group = b.String("group");
    row.reference = b.String("reference");
    row.samplesPerProbe = b.Integer("samplesPerProbe");
    row.targetRelError = b.Number("targetRelError");
    row.shOrder = int(b.Integer("shOrder"));
    row.maxDepth = int(b.Integer("maxDepth"));
    row.batches = int(b.Integer("batches"));
    row.estimator = b.String("estimator");
    row.sampler = b.String("sampler");
    row.russianRoulette = b.Bool("russianRoulette");
    row.threads = int(b.Integer("threads"));
    row.wallSeconds = b.Number("wallSeconds");
    row.cpuSeconds = b.Number("cpuSeconds");
    row.rays = b.Integer("rays");
    row.samples = b.Integer("samples");
    row.probes = b.Integer("probes");
    row.repeatsIdentical = b.Bool("repeatsIdentical");
    ErrorSummary& e = row.error;
    e.probes = row.probes;
    e.meanIrradianceRel = b.Number("irradianceErrorMean");
    e.medianIrradianceRel = b.Number("irradianceErrorMedian");
    e.maxIrradianceRel = b.Number("irradianceErrorMax");
    e.meanRadianceRel = b.Number("radianceErrorMean");
    e.rmsL0Rel = b.Number("l0ErrorRms");
    e.rmsIrradianceLumRel = b.Number("irradianceLumErrorRms");
    e.meanStdError = b.Number("stdErrorMean");
    e.meanStdErrorL0 = b.Number("stdErrorL0Mean");
    e.honesty = b.Number("honesty");
    e.honestyL0 = b.Number("honestyL0");
    e.honestyIrradiance = b.Number("honestyIrradiance");
    e.meanSamples = b.Number("meanSamples");
    e.meanSignedL0 = b.Number("meanSignedL0");
    e.meanSignedL0StdError = b.Number("meanSignedL0StdError");
    row.stoppedByTarget = b.Number("stoppedByTarget");
    row.measuredWithinTarget = b.Number("measuredWithinTarget");
    row.stoppedRmsOverTarget = b.Number("stoppedRmsOverTarget");
    r.rows.push_back(row);
  });
  ForEachObject(f, "throughput", &error, [&](Fields& t) {
    ThroughputInfo tp;
    tp.scene = t.String("scene");
    tp.raw.triangles = t.Integer("triangles");
    tp.tracerCpuMrays = t.Number("tracerCpuMrays");
    tp.tracerWallMrays = t.Number("tracerWallMrays");
    tp.rays = t.Integer("rays");
    tp.intersectRays = t.Integer("intersectRays");
    tp.shadowRays = t.Integer("shadowRays");
    tp.bakeCpuSeconds = t.Number("bakeCpuSeconds");
    tp.embreeOnlySeconds = t.Number("embreeShare") * tp.bakeCpuSeconds;
    tp.setupCpuSeconds = t.Number("setupCpuSeconds");
    tp.setupRays = t.Integer("setupRays");
    tp.pairedFractions = t.Numbers("pairedFractions");
    for (double cpu : t.Numbers("pairedCpus")) tp.pairedCpus.push_back(int(cpu));
    ForEachObject(t, "raw", &error, [&](Fields& w) {
      RawRate rate;
      rate.rays = w.String("rays");
      rate.api = w.String("api");
      rate.threads = int(w.Integer("threads"));
      rate.wallMraysPerSecond = w.Number("wallMrays");
      rate.cpuMraysPerSecond = w.Number("cpuMrays");
      tp.raw.rates.push_back(rate);
    });
    if (t.Has("replay")) {  // since the replay of the tracer's own rays
      Fields p(t.Object("replay"), t.Path("replay"), &error);
      ReplayInfo& rp = tp.replay;
      rp.measured = true;
      rp.stride = uint64_t(p.Integer("stride"));
      rp.calls = p.Integer("calls");
      for (int k = 0; k < kRayKinds; ++k) {
        Fields kind(p.Object(RayKindName(RayKind(k))), p.Path(RayKindName(RayKind(k))), &error);
        rp.rays[k] = kind.Integer("rays");
        rp.cast[k] = kind.Integer("cast");
      }
      rp.packed = p.Integer("packed");
      rp.tracerMrays = p.Numbers("tracerMrays");
      rp.singleMrays = p.Numbers("singleMrays");
      rp.packetMrays = p.Numbers("packetMrays");
      rp.fractions = p.Numbers("fractions");
      for (double cpu : p.Numbers("cpus")) rp.cpus.push_back(int(cpu));
      ForEachObject(p, "rates", &error, [&](Fields& w) {
        ReplayRate rate;
        rate.rays = w.String("rays");
        rate.api = w.String("api");
        rate.count = w.Integer("count");
        rate.cpuMraysPerSecond = w.Number("cpuMrays");
        rp.rates.push_back(rate);
      });
    }
    r.throughput.push_back(tp);
  });
  {
    Fields s(f.Object("scaling"), f.Path("scaling"), &error);
    r.scaling.scene = s.String("scene");
    r.scaling.samplesPerProbe = s.Integer("samplesPerProbe");
    r.scaling.probes = s.Integer("probes");
    r.scaling.wall1 = s.Numbers("wall1");
    r.scaling.wall2 = s.Numbers("wall2");
    r.scaling.cpu1 = s.Numbers("cpu1");
    r.scaling.cpu2 = s.Numbers("cpu2");
    r.scaling.load = s.Number("load");
    r.scaling.rawRatio = s.Number("rawEmbreeRatio");
  }
  {
    Fields m(f.Object("memory"), f.Path("memory"), &error);
    MemoryInfo& mem = r.memory;
    mem.measured = m.Bool("measured");
    mem.note = m.String("note");
    mem.probes = m.Integer("probes");
    mem.samplesPerProbe = m.Integer("samplesPerProbe");
    mem.bakeSeconds = m.Number("bakeSeconds");
    mem.baselineRss = m.Integer("baselineRssBytes");
    mem.peakBake = m.Integer("peakBakeBytes");
    mem.shBytes = m.Integer("shBytes");
    mem.volumeBytes = m.Integer("volumeBytes");
    mem.peakWriteExtra = m.Integer("peakWriteExtraBytes");
    mem.vdbBytes = m.Integer("vdbBytes");
    mem.writeSeconds = m.Number("writeSeconds");
  }
  if (!error.ok()) return error;
  return r;
}

}  // namespace probebake::bench
