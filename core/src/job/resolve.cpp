// Settings, presets, grid and environment orientation: the pure functions of probebake/job/job.h.
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cmath>

#include "grid_internal.h"
#include "probebake/base/check.h"
#include "probebake/job/job.h"

namespace probebake {

QualityPreset PresetFor(v1::BakeSettings::Quality quality) {
  // Calibrated with the accuracy benchmark on its hardest scene, the demo room; what each preset
  // costs and buys there is measured in docs/accuracy-and-speed.md. The depths: PREVIEW's 6 loses
  // less light than its noise, PRODUCTION's 8 about a tenth of its noise, REFERENCE's 32 nothing
  // measurable. The targets let easy probes stop early: adaptive probes sample at least 10 of their
  // 64 batches (a first round of 8 and a confirming one of 2) before they may stop.
  switch (quality) {
    case v1::BakeSettings::PREVIEW:
      return {512, 6, 0.05};
    case v1::BakeSettings::PRODUCTION:
      return {4096, 8, 0.02};
    case v1::BakeSettings::REFERENCE:
      return {16384, 32, 0};
    default:
      return {1024, 8, 0};
  }
}

BakeSettings ResolveSettings(const v1::BakeSettings& s) {
  const QualityPreset preset = PresetFor(s.quality());
  BakeSettings r;
  r.shOrder = s.has_sh_order() ? s.sh_order() : kDefaultShOrder;
  r.samplesPerProbe = s.has_samples_per_probe() ? s.samples_per_probe() : preset.samplesPerProbe;
  r.maxDepth = s.has_max_depth() ? s.max_depth() : preset.maxDepth;
  r.targetRelError = s.has_target_rel_error() ? s.target_rel_error() : preset.targetRelError;
  r.seed = s.has_seed() ? s.seed() : 1;
  r.irradiance = s.has_irradiance() && s.irradiance();
  switch (s.window()) {
    case v1::BakeSettings::HANNING:
      r.window = ShWindow::kHanning;
      break;
    case v1::BakeSettings::LANCZOS:
      r.window = ShWindow::kLanczos;
      break;
    case v1::BakeSettings::AUTO:
      r.window = ShWindow::kAuto;
      break;
    default:
      r.window = ShWindow::kNone;
      break;
  }
  r.windowWidth = s.has_window_width() ? s.window_width() : r.shOrder + 1;
  switch (s.estimator()) {
    case v1::BakeSettings::LIGHT_SAMPLING:
      r.estimator = Estimator::kLightSampling;
      break;
    case v1::BakeSettings::DIRECTION_SAMPLING:
      r.estimator = Estimator::kDirectionSampling;
      break;
    default:
      r.estimator = Estimator::kNeeMis;
      break;
  }
  r.sampler = s.sampler() == v1::BakeSettings::INDEPENDENT ? SamplerKind::kIndependent
                                                           : SamplerKind::kSobol;
  r.russianRoulette = s.has_russian_roulette() ? s.russian_roulette() : true;
  r.rrMinDepth = s.has_rr_min_depth() ? s.rr_min_depth() : 3;
  // Few batches keep each one's point set large, which is where its quasi-Monte Carlo accuracy
  // lies (core/src/bake/probe_integrator.h); 4 still give a probe's std_error to about +-30%, since
  // it pools every coefficient's spread (docs/accuracy-and-speed.md). Adaptive probes may stop
  // after any round of batches, so there the batch is the granularity of their sample counts: 64
  // batches let an easy probe stop at 10/64 of the cap.
  r.batches = s.has_batches() ? s.batches() : (r.targetRelError > 0 ? 64 : 4);
  r.backfaceFraction = s.has_backface_fraction() ? s.backface_fraction() : 0.5;
  r.relocationMaxOffset = s.has_relocation_max_offset() ? s.relocation_max_offset() : 0;
  r.visibility = s.has_visibility() && s.visibility();
  r.skyTransferOrder = s.has_sky_transfer() ? s.sky_transfer().order() : 0;
  return r;
}

v1::BakeSettings SettingsToProto(const BakeSettings& r) {
  v1::BakeSettings s;
  s.set_sh_order(r.shOrder);
  s.set_samples_per_probe(r.samplesPerProbe);
  s.set_max_depth(r.maxDepth);
  s.set_target_rel_error(r.targetRelError);
  s.set_seed(r.seed);
  s.set_irradiance(r.irradiance);
  switch (r.window) {
    case ShWindow::kNone:
      s.set_window(v1::BakeSettings::NONE);
      break;
    case ShWindow::kHanning:
      s.set_window(v1::BakeSettings::HANNING);
      break;
    case ShWindow::kLanczos:
      s.set_window(v1::BakeSettings::LANCZOS);
      break;
    case ShWindow::kAuto:
      s.set_window(v1::BakeSettings::AUTO);
      break;
  }
  s.set_window_width(r.windowWidth);
  switch (r.estimator) {
    case Estimator::kNeeMis:
      s.set_estimator(v1::BakeSettings::NEE_MIS);
      break;
    case Estimator::kLightSampling:
      s.set_estimator(v1::BakeSettings::LIGHT_SAMPLING);
      break;
    case Estimator::kDirectionSampling:
      s.set_estimator(v1::BakeSettings::DIRECTION_SAMPLING);
      break;
  }
  s.set_sampler(r.sampler == SamplerKind::kIndependent ? v1::BakeSettings::INDEPENDENT
                                                       : v1::BakeSettings::SOBOL);
  s.set_russian_roulette(r.russianRoulette);
  s.set_rr_min_depth(r.rrMinDepth);
  s.set_batches(r.batches);
  s.set_backface_fraction(r.backfaceFraction);
  s.set_relocation_max_offset(r.relocationMaxOffset);
  s.set_visibility(r.visibility);
  // Set only when on: the settings of bakes without it (their digests and metadata) are unchanged.
  if (r.skyTransferOrder > 0) s.mutable_sky_transfer()->set_order(r.skyTransferOrder);
  return s;
}

std::string SettingsToJson(const BakeSettings& settings) {
  std::string json;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = false;
  // Every field of SettingsToProto has presence and is set, so each is printed.
  const auto status =
      google::protobuf::util::MessageToJsonString(SettingsToProto(settings), &json, options);
  // Printing a valid message cannot fail; a failure here is a protobuf bug, not user input.
  PB_CHECK(status.ok());
  return json;
}

ProbeGrid ResolveGrid(const v1::Grid& grid) {
  ProbeGrid g;
  PB_CHECK_EQ(grid.min_size(), 3);
  PB_CHECK_EQ(grid.max_size(), 3);
  const Vec3d lo(grid.min(0), grid.min(1), grid.min(2));
  const Vec3d hi(grid.max(0), grid.max(1), grid.max(2));
  g.origin = lo;
  if (grid.counts_size() == 3) {
    double smallest = 0;  // the smallest spacing of the axes with several probes
    for (int a = 0; a < 3; ++a) {
      g.counts[a] = grid.counts(a);
      if (g.counts[a] > 1) {
        g.spacing[a] = (hi[a] - lo[a]) / (g.counts[a] - 1);
        smallest = smallest == 0 ? g.spacing[a] : std::min(smallest, g.spacing[a]);
      }
    }
    for (int a = 0; a < 3; ++a)
      if (g.counts[a] == 1) g.spacing[a] = smallest > 0 ? smallest : 1;
  } else {
    const google::protobuf::Value& v = grid.spacing();
    for (int a = 0; a < 3; ++a) {
      g.spacing[a] = v.kind_case() == google::protobuf::Value::kNumberValue
                         ? v.number_value()
                         : v.list_value().values(a).number_value();
      g.counts[a] = int(job_internal::ProbesOnAxis(lo[a], hi[a], g.spacing[a]));
    }
  }
  switch (grid.placement()) {
    case v1::Grid::ALL:
      g.placement = Placement::kAll;
      break;
    case v1::Grid::NEAR_SURFACES:
      g.placement = Placement::kNearSurfaces;
      g.surfaceDistance = grid.surface_distance();
      break;
    default:
      g.placement = Placement::kOutsideGeometry;
      break;
  }
  return g;
}

Mat3d EnvironmentWorldFromMap(v1::EnvironmentMap::Up up, double rotationDeg) {
  // cos and sin of the angle in degrees, exact at multiples of 90 degrees so that quarter turns
  // permute axes without rounding.
  double r = std::fmod(rotationDeg, 360.0);
  if (r < 0) r += 360;
  double c, s;
  if (r == 0 || r == 360) {
    c = 1, s = 0;
  } else if (r == 90) {
    c = 0, s = 1;
  } else if (r == 180) {
    c = -1, s = 0;
  } else if (r == 270) {
    c = 0, s = -1;
  } else {
    const double radians = r * (M_PI / 180);
    c = std::cos(radians), s = std::sin(radians);
  }
  if (up == v1::EnvironmentMap::Z) {
    // Map (x, y, z) -> world (x, -z, y), then a right-handed turn about world +Z (counter-clockwise
    // seen from above, +Z toward the viewer).
    const Mat3d upFromMap = Mat3d::FromRows({1, 0, 0}, {0, 0, -1}, {0, 1, 0});
    const Mat3d rotation = Mat3d::FromRows({c, -s, 0}, {s, c, 0}, {0, 0, 1});
    return rotation * upFromMap;
  }
  // Y up: map directions are world directions; a right-handed turn about world +Y.
  return Mat3d::FromRows({c, 0, s}, {0, 1, 0}, {-s, 0, c});
}

}  // namespace probebake
