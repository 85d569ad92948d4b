// The guard of kBakerVersion: small fixed bakes, one per estimator, sampler and feature of the
// tracer, each hashed (SHA-256 of every number a volume stores), against the hashes recorded per
// baker version in tests/data/golden/baker_bits.txt.
//
// The result cache keys every volume by its job digest, which includes kBakerVersion, so the
// version must change exactly when the bits do:
//   - the bits changed and kBakerVersion did not: a cached volume would be served for a job the
//     new baker bakes differently (fails: bump the version and record its hashes);
//   - kBakerVersion changed and the bits did not: every cached volume is thrown away for nothing
//     (fails against the previous version's line).
// Both failures print the lines to record. The file keeps every version's hashes, so the history
// of which change moved which case stays readable.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "probebake/bake/bake.h"
#include "probebake/base/log.h"
#include "probebake/base/status.h"
#include "probebake/base/version.h"
#include "probebake/job/asset_source.h"
#include "probebake/job/digest.h"
#include "probebake/job/job.h"
#include "probebake/job/job_json.h"

namespace probebake {
namespace {

const std::string kDataDir = PROBEBAKE_TEST_DATA_DIR;
const std::string kBitsFile = kDataDir + "/golden/baker_bits.txt";

// SHA-256 of what a volume stores: which probes are active, every coefficient plane, validity,
// errors, sample counts, the per-probe AUTO window and the window's record. Not its statistics
// (time, rays counted), which are not part of the result.
std::string HashVolume(const ProbeVolume& v) {
  std::string bytes;
  const auto add = [&](const void* data, size_t size) {
    bytes.append(static_cast<const char*>(data), size);
  };
  const auto addFloats = [&](const std::vector<float>& f) {
    const uint64_t n = f.size();
    add(&n, sizeof n);
    add(f.data(), f.size() * sizeof(float));
  };
  add(&v.shOrder, sizeof v.shOrder);
  add(v.active.data(), v.active.size());
  for (const auto& plane : v.radiance) addFloats(plane);
  for (const auto& plane : v.irradiance) addFloats(plane);
  addFloats(v.validity);
  addFloats(v.stdError);
  addFloats(v.stdErrorL0);
  addFloats(v.sampleCount);
  addFloats(v.autoWindowT);
  bytes += v.window;
  // Format 3's optional planes, only when present: hashes of bakes without them are unchanged.
  if (!v.offset.empty()) addFloats(v.offset);
  if (!v.filled.empty()) addFloats(v.filled);
  for (const auto& plane : v.visibility) addFloats(plane);
  if (v.skyTransferOrder > 0) {
    add(&v.skyTransferOrder, sizeof v.skyTransferOrder);
    for (const auto& plane : v.skyTransfer) addFloats(plane);
  }
  return Sha256Hex(bytes);
}

// tests/data/demo/mirrored_boxes.gltf (a unit box under a plain node at x in [-1.5, -0.5] and a
// node mirroring x at [0.5, 1.5]) in a closed room, probes at both boxes' centres.
constexpr const char* kMirroredNodeJson = R"({
  "scene": {
    "materials": [{"name": "wall", "albedo": [0.7, 0.7, 0.7]}],
    "meshes": [
      {"name": "room", "material": "wall",
       "positions": [-3,-2,-0.01, 3,-2,-0.01, -3,2,-0.01, 3,2,-0.01, -3,-2,3, 3,-2,3, -3,2,3, 3,2,3],
       "indices": [0,1,3, 0,3,2, 4,6,7, 4,7,5, 0,4,5, 0,5,1, 2,3,7, 2,7,6, 0,2,6, 0,6,4,
                   1,5,7, 1,7,3]},
      {"name": "boxes", "file": "mirrored_boxes.gltf"}
    ],
    "lights": [{"point": {"position": [0, 0, 2.5], "intensity": [5, 5, 4]}}]
  },
  "grid": {"min": [-1, 0, 0.5], "max": [1, 0, 1.5], "counts": [3, 1, 2], "placement": "ALL"},
  "settings": {"shOrder": 2, "samplesPerProbe": 128, "maxDepth": 4, "seed": 3}
})";

v1::JobSpec DemoSpec() {
  absl::StatusOr<v1::JobSpec> spec = ReadJobFile(kDataDir + "/demo/demo.json");
  EXPECT_TRUE(spec.ok()) << spec.status();
  // A 4 x 3 x 2 grid over the room: probes near the window, the light and the boxes.
  v1::Grid* grid = spec->mutable_grid();
  grid->clear_spacing();
  grid->clear_counts();
  for (int c : {4, 3, 2}) grid->add_counts(c);
  spec->mutable_settings()->set_samples_per_probe(256);
  return *spec;
}

// A closed room (4 x 4 x 3) lit by every kind of light, a uniform sky through an open roof and an
// emissive panel.
constexpr const char* kAllLightsJson = R"({
  "scene": {
    "materials": [{"name": "wall", "albedo": [0.7, 0.6, 0.5]},
                  {"name": "panel", "albedo": [0.2, 0.2, 0.2], "emission": [3, 2, 1]}],
    "meshes": [
      {"name": "floor", "material": "wall", "positions": [-2,-2,0, 2,-2,0, 2,2,0, -2,2,0],
       "indices": [0,1,2, 0,2,3]},
      {"name": "west", "material": "wall", "positions": [-2,-2,0, -2,2,0, -2,2,3, -2,-2,3],
       "indices": [0,1,2, 0,2,3]},
      {"name": "panel", "material": "panel",
       "positions": [1.99,-0.5,1, 1.99,-0.5,2, 1.99,0.5,2, 1.99,0.5,1], "indices": [0,1,2, 0,2,3]}
    ],
    "lights": [
      {"point": {"position": [0.5, 0.5, 2.5], "intensity": [4, 4, 3]}},
      {"spot": {"position": [-1, 1, 2.8], "direction": [0.3, -0.2, -1], "intensity": [20, 18, 15],
                "innerAngleDeg": 15, "outerAngleDeg": 35}},
      {"directional": {"direction": [0.2, 0.3, -1], "irradiance": [1, 1, 1]}},
      {"directional": {"direction": [-0.4, 0.1, -0.8], "irradiance": [6, 5, 4],
                       "angularDiameterDeg": 2}},
      {"rect": {"corner": [-0.5, -1.5, 2.9], "edge1": [1, 0, 0], "edge2": [0, 0.6, 0],
                "radiance": [5, 5, 5]}},
      {"rect": {"corner": [0, 1.5, 0.5], "edge1": [0.8, 0, 0], "edge2": [0.3, 0, 0.5],
                "radiance": [2, 3, 4], "twoSided": true}},
      {"disk": {"center": [-1.5, -1.5, 1.5], "normal": [0.7071067811865476, 0.7071067811865476, 0],
                "radius": 0.2, "radiance": [8, 6, 4]}},
      {"sphere": {"center": [1, -1, 0.6], "radius": 0.1, "radiance": [30, 30, 20]}}
    ],
    "environment": {"uniform": {"radiance": [0.3, 0.4, 0.6]}}
  },
  "grid": {"min": [-1.5, -1.5, 0.5], "max": [1.5, 1.5, 2.5], "counts": [3, 3, 2],
           "placement": "NEAR_SURFACES", "surfaceDistance": 3},
  "settings": {"shOrder": 2, "samplesPerProbe": 256, "maxDepth": 5, "seed": 7,
               "irradiance": true, "window": "HANNING"}
})";

v1::JobSpec AllLightsSpec() {
  absl::StatusOr<v1::JobSpec> spec = ParseJobJson(kAllLightsJson);
  EXPECT_TRUE(spec.ok()) << spec.status();
  return *spec;
}

// The demo room with its ceiling light split into 12 x 8 small lights and 80 point lights along
// the walls: both kinds past kLightTreeMinLights, chosen through light trees.
v1::JobSpec ManyLightsSpec() {
  v1::JobSpec spec = DemoSpec();
  v1::Scene* scene = spec.mutable_scene();
  scene->clear_lights();
  for (int i = 0; i < 12; ++i) {
    for (int j = 0; j < 8; ++j) {
      v1::RectLight* r = scene->add_lights()->mutable_rect();
      for (double x : {-3.0 + 0.5 * i, -2.0 + 0.5 * j, 2.99}) r->add_corner(x);
      for (double x : {0.0, 0.2, 0.0}) r->add_edge1(x);
      for (double x : {0.2, 0.0, 0.0}) r->add_edge2(x);
      for (double x : {20.0, 18.0, 16.0}) r->add_radiance(x);
    }
  }
  for (int i = 0; i < 80; ++i) {
    v1::PointLight* p = scene->add_lights()->mutable_point();
    const double t = i / 80.0;
    for (double x : {-3.8 + 7.6 * t, (i % 2 ? 2.8 : -2.8), 0.3 + 2.4 * ((i * 7) % 10) / 10.0})
      p->add_position(x);
    for (double x : {0.2, 0.15, 0.1}) p->add_intensity(x);
  }
  scene->clear_environment();
  return spec;
}

struct GoldenCase {
  std::string name;
  std::function<v1::JobSpec()> spec;
};

std::vector<GoldenCase> Cases() {
  using Settings = v1::BakeSettings;
  const auto demoWith = [](std::function<void(Settings*)> change) {
    return [change] {
      v1::JobSpec spec = DemoSpec();
      change(spec.mutable_settings());
      return spec;
    };
  };
  return {
      {"demo_nee_mis_sobol", demoWith([](Settings*) {})},
      {"demo_light_sampling",
       demoWith([](Settings* s) { s->set_estimator(Settings::LIGHT_SAMPLING); })},
      {"demo_direction_sampling",
       demoWith([](Settings* s) { s->set_estimator(Settings::DIRECTION_SAMPLING); })},
      {"demo_independent", demoWith([](Settings* s) { s->set_sampler(Settings::INDEPENDENT); })},
      // Fewer samples per call than packets need: every ray traced alone.
      {"demo_few_samples", demoWith([](Settings* s) { s->set_samples_per_probe(64); })},
      {"demo_no_roulette_order1", demoWith([](Settings* s) {
         s->set_russian_roulette(false);
         s->set_sh_order(1);
       })},
      {"demo_adaptive_auto_window", demoWith([](Settings* s) {
         s->set_samples_per_probe(1024);
         s->set_target_rel_error(0.05);
         s->set_sh_order(3);
         s->set_window(Settings::AUTO);
       })},
      {"demo_medium",
       [] {
         v1::JobSpec spec = DemoSpec();
         v1::Medium* m = spec.mutable_scene()->mutable_medium();
         for (double x : {0.02, 0.03, 0.04}) m->add_sigma_a(x);
         for (double x : {0.10, 0.08, 0.06}) m->add_sigma_s(x);
         m->set_g(0.4);
         spec.mutable_settings()->set_samples_per_probe(128);
         return spec;
       }},
      // Relocation (grid points inside the demo's boxes and on its floor move) and visibility.
      {"demo_relocation_visibility", demoWith([](Settings* s) {
         s->set_relocation_max_offset(0.4);
         s->set_visibility(true);
       })},
      // Adaptive sampling with visibility (baker 19: no probe stops before 256 samples, so that
      // its moments hold a few rays a texel; at a 20% target probes stopped at 80).
      {"demo_adaptive_visibility", demoWith([](Settings* s) {
         s->set_samples_per_probe(512);
         s->set_batches(64);
         s->set_target_rel_error(0.2);
         s->set_visibility(true);
       })},
      // Sky transfer: the demo's sky into T, its lamp into the radiance.
      {"demo_sky_transfer", demoWith([](Settings* s) {
         s->set_samples_per_probe(128);
         s->mutable_sky_transfer()->set_order(2);
       })},
      {"all_lights", AllLightsSpec},
      {"all_lights_independent",
       [] {
         v1::JobSpec spec = AllLightsSpec();
         spec.mutable_settings()->set_sampler(Settings::INDEPENDENT);
         return spec;
       }},
      {"many_lights", ManyLightsSpec},
      // A glTF box placed plainly and by a mirroring node (baker 18: the mirrored copy keeps its
      // front faces), a probe inside each.
      {"gltf_mirrored_node",
       [] {
         absl::StatusOr<v1::JobSpec> spec = ParseJobJson(kMirroredNodeJson);
         EXPECT_TRUE(spec.ok()) << spec.status();
         return *spec;
       }},
  };
}

absl::StatusOr<std::string> BakeAndHash(const v1::JobSpec& spec) {
  const JobLimits limits;
  PB_ASSIGN_OR_RETURN(
      const BakeJob job,
      BuildBakeJob(spec, LocalAssetSource(kDataDir + "/demo", "", limits.maxAssetBytes), limits));
  BakeOptions options;
  options.threads = 2;
  PB_ASSIGN_OR_RETURN(const ProbeVolume volume, Bake(job, options));
  return HashVolume(volume);
}

// version -> case -> hash, from lines "<version> <case> <sha256 hex>" ('#' starts a comment).
std::map<int, std::map<std::string, std::string>> ReadRecordedBits() {
  std::map<int, std::map<std::string, std::string>> bits;
  std::ifstream in(kBitsFile);
  EXPECT_TRUE(in.good()) << "cannot read " << kBitsFile;
  std::string line;
  int lineNumber = 0;
  while (std::getline(in, line)) {
    ++lineNumber;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    int version = 0;
    std::string name, hash;
    fields >> version >> name >> hash;
    EXPECT_TRUE(fields && IsSha256Hex(hash)) << kBitsFile << ":" << lineNumber << ": " << line;
    bits[version][name] = hash;
  }
  return bits;
}

TEST(GoldenBits, KBakerVersionChangesExactlyWhenTheBitsDo) {
  Logger("bake")->set_level(spdlog::level::warn);
  Logger("job")->set_level(spdlog::level::warn);
  std::map<std::string, std::string> baked;
  std::string lines;
  for (const GoldenCase& c : Cases()) {
    absl::StatusOr<std::string> hash = BakeAndHash(c.spec());
    ASSERT_TRUE(hash.ok()) << c.name << ": " << hash.status();
    baked[c.name] = *hash;
    lines += std::to_string(kBakerVersion) + " " + c.name + " " + *hash + "\n";
  }
  const auto recorded = ReadRecordedBits();
  const std::string record = "\nThe lines for version " + std::to_string(kBakerVersion) + " (in " +
                             kBitsFile + "):\n" + lines;

  const auto current = recorded.find(kBakerVersion);
  ASSERT_NE(current, recorded.end())
      << "kBakerVersion " << kBakerVersion << " has no recorded bits." << record;
  for (const auto& [name, hash] : baked) {
    const auto it = current->second.find(name);
    ASSERT_NE(it, current->second.end()) << "case " << name << " not recorded." << record;
    EXPECT_EQ(it->second, hash) << "case " << name << ": the bits changed but kBakerVersion ("
                                << kBakerVersion
                                << ", core/include/probebake/base/version.h) did not; bump it."
                                << record;
  }
  EXPECT_EQ(current->second.size(), baked.size()) << "recorded cases that no longer exist";

  // The version before this one, where its bits were recorded: at least one case must differ.
  const auto before = std::make_reverse_iterator(current);
  if (before != recorded.rend()) {
    bool anyDiffers = false;
    for (const auto& [name, hash] : baked) {
      const auto it = before->second.find(name);
      anyDiffers = anyDiffers || it == before->second.end() || it->second != hash;
    }
    EXPECT_TRUE(anyDiffers) << "kBakerVersion " << kBakerVersion << " bakes the same bits as "
                            << before->first << ": the bump throws every cached volume away "
                            << "for nothing; revert it.";
  }
}

// The hash reads every stored number: a one-ulp change of any of them changes it.
TEST(GoldenBits, TheHashSeesEveryStoredNumber) {
  ProbeVolume v;
  v.shOrder = 1;
  v.active = {1, 1};
  v.radiance.assign(4, std::vector<float>(6, 0.5f));
  v.irradiance.assign(4, std::vector<float>(6, 0.25f));
  v.validity = {1, 1};
  v.stdError = {0.01f, 0.02f};
  v.stdErrorL0 = {0.005f, 0.01f};
  v.sampleCount = {64, 64};
  const std::string base = HashVolume(v);
  const std::vector<std::function<void(ProbeVolume*)>> nudges = {
      [](ProbeVolume* x) { x->radiance[3][5] = std::nextafter(x->radiance[3][5], 1.0f); },
      [](ProbeVolume* x) { x->irradiance[0][0] = std::nextafter(x->irradiance[0][0], 1.0f); },
      [](ProbeVolume* x) { x->validity[1] = 0; },
      [](ProbeVolume* x) { x->stdError[0] = std::nextafter(x->stdError[0], 1.0f); },
      [](ProbeVolume* x) { x->stdErrorL0[1] = std::nextafter(x->stdErrorL0[1], 1.0f); },
      [](ProbeVolume* x) { x->sampleCount[1] = 65; },
      [](ProbeVolume* x) { x->active[0] = 0; },
      [](ProbeVolume* x) { x->window = "HANNING"; },
      [](ProbeVolume* x) {
        x->autoWindowT = {0, 0.1f};
      },
      [](ProbeVolume* x) { x->offset = {0, 0, 0, 0, 0, 0.125f}; },
      [](ProbeVolume* x) {
        x->filled = {0, 1};
      },
      [](ProbeVolume* x) { x->visibility.assign(64, std::vector<float>(6, 1.0f)); },
  };
  for (size_t k = 0; k < nudges.size(); ++k) {
    ProbeVolume changed = v;
    nudges[k](&changed);
    EXPECT_NE(HashVolume(changed), base) << "nudge " << k;
  }
}

}  // namespace
}  // namespace probebake
