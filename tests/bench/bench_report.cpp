#include "bench_report.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <string_view>

#include "bench_util.h"
#include "core/src/bake/light_set.h"
#include "probebake/base/status.h"

namespace probebake::bench {
namespace {

constexpr double kMiB = 1024.0 * 1024.0;
// Error levels of the time-to-error tables.
constexpr double kErrorLevels[] = {0.1, 0.05, 0.02, 0.01, 0.005, 0.002};

// "median 0.57 (0.55 to 0.59, 3 pairs)", or "-" with no readings.
std::string PairedText(std::vector<double> fractions) {
  if (fractions.empty()) return "-";
  std::sort(fractions.begin(), fractions.end());
  if (fractions.size() == 1) return Format("%.2f (1 pair)", fractions[0]);
  return Format("median %.2f (%.2f to %.2f, %zu pairs)", Median(fractions), fractions.front(),
                fractions.back(), fractions.size());
}

std::string Pct(double fraction, int digits = 3) {
  if (!(fraction >= 0) || !std::isfinite(fraction)) return "-";
  return Format("%.*g%%", digits, 100 * fraction);
}

std::string Num(double v, int digits = 3) {
  if (!std::isfinite(v)) return "-";
  return Format("%.*g", digits, v);
}

// The scaling section's figures: the best (least) time of each set of repeats; nullopt when the
// scaling was not measured.
struct ScalingBest {
  double wall1, wall2, cpu1, cpu2;
};
std::optional<ScalingBest> BestOf(const ScalingInfo& sc) {
  if (sc.wall1.empty() || sc.wall2.empty() || sc.cpu1.empty() || sc.cpu2.empty())
    return std::nullopt;
  return ScalingBest{*std::min_element(sc.wall1.begin(), sc.wall1.end()),
                     *std::min_element(sc.wall2.begin(), sc.wall2.end()),
                     *std::min_element(sc.cpu1.begin(), sc.cpu1.end()),
                     *std::min_element(sc.cpu2.begin(), sc.cpu2.end())};
}

// ---- curves ----

struct Point {
  double time, error;
};

// The ladder curve of (scene, config): (CPU seconds, mean relative irradiance error) by sample
// count.
std::vector<Point> Curve(const BenchResults& r, const std::string& scene,
                         const std::string& config) {
  std::vector<std::pair<int64_t, Point>> points;
  for (const BakeRow& row : r.rows)
    if (row.scene == scene && row.config == config && row.group == "ladder")
      points.push_back({row.samplesPerProbe, {row.cpuSeconds, row.error.meanIrradianceRel}});
  std::sort(points.begin(), points.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Point> out;
  for (const auto& p : points) out.push_back(p.second);
  return out;
}

enum class Reach { kInterpolated, kExtrapolated, kBelowAtFirst, kNone };

struct TimeTo {
  double time = 0;
  Reach how = Reach::kNone;
};

// Time at which the curve first reaches `error`: log-log interpolation between the two ladder
// points around it; past the last point, extrapolated with the Monte Carlo rate error ~ t^-1/2.
TimeTo TimeToError(const std::vector<Point>& curve, double error) {
  TimeTo out;
  if (curve.empty() || !(error > 0)) return out;
  if (curve.front().error <= error) return {curve.front().time, Reach::kBelowAtFirst};
  for (size_t i = 1; i < curve.size(); ++i) {
    if (curve[i].error <= error) {
      const Point a = curve[i - 1], b = curve[i];
      const double f = std::log(error / a.error) / std::log(b.error / a.error);
      return {std::exp(std::log(a.time) + f * std::log(b.time / a.time)), Reach::kInterpolated};
    }
  }
  const Point last = curve.back();
  if (!(last.error > 0)) return out;
  return {last.time * (last.error / error) * (last.error / error), Reach::kExtrapolated};
}

std::string TimeText(const TimeTo& t) {
  switch (t.how) {
    case Reach::kInterpolated:
      return Format("%.3g s", t.time);
    case Reach::kExtrapolated:
      return Format("~%.3g s", t.time);
    case Reach::kBelowAtFirst:
      return Format("<= %.3g s", t.time);
    case Reach::kNone:
      return "-";
  }
  return "-";
}

// ---- SVG ----

const char* kColours[] = {"#d62728", "#ff7f0e", "#9467bd", "#1f77b4", "#17becf",
                          "#2ca02c", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22"};

std::string Escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '&')
      out += "&amp;";
    else if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '"')
      out += "&quot;";
    else
      out += c;
  }
  return out;
}

std::string Plot(const BenchResults& r, const std::string& scene, const std::string& title,
                 const std::string& subtitle) {
  const double width = 1000, height = 640, left = 80, right = 330, top = 56, bottom = 60;
  const double plotW = width - left - right, plotH = height - top - bottom;
  // Data ranges (log decades enclosing every point).
  double tMin = std::numeric_limits<double>::infinity(), tMax = 0, eMin = tMin, eMax = 0;
  for (const BakeRow& row : r.rows) {
    if (row.scene != scene || !(row.cpuSeconds > 0) || !(row.error.meanIrradianceRel > 0)) continue;
    tMin = std::min(tMin, row.cpuSeconds);
    tMax = std::max(tMax, row.cpuSeconds);
    eMin = std::min(eMin, row.error.meanIrradianceRel);
    eMax = std::max(eMax, row.error.meanIrradianceRel);
  }
  if (!(tMax > 0)) return "";
  const double lt0 = std::floor(std::log10(tMin)), lt1 = std::ceil(std::log10(tMax));
  const double le0 = std::floor(std::log10(eMin)), le1 = std::ceil(std::log10(eMax));
  auto X = [&](double t) { return left + plotW * (std::log10(t) - lt0) / (lt1 - lt0); };
  auto Y = [&](double e) { return top + plotH * (le1 - std::log10(e)) / (le1 - le0); };

  std::string svg = Format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" "
      "viewBox=\"0 0 %.0f %.0f\" font-family=\"sans-serif\" font-size=\"12\">\n"
      "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n",
      width, height, width, height);
  svg += Format("<text x=\"%.0f\" y=\"20\" font-size=\"15\" font-weight=\"bold\">%s</text>\n", left,
                Escape(title).c_str());
  svg +=
      Format("<text x=\"%.0f\" y=\"38\" fill=\"#555\">%s</text>\n", left, Escape(subtitle).c_str());
  // Grid and ticks: decades with 2 and 5 minor lines.
  for (double d = lt0; d <= lt1; ++d) {
    for (int m : {1, 2, 5}) {
      const double t = m * std::pow(10.0, d);
      if (std::log10(t) > lt1 + 1e-9) break;
      const double x = X(t);
      svg += Format("<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"%s\"/>\n", x,
                    top, x, top + plotH, m == 1 ? "#bbb" : "#eee");
      if (m == 1)
        svg += Format("<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"middle\">%g</text>\n", x,
                      top + plotH + 18, t);
    }
  }
  for (double d = le0; d <= le1; ++d) {
    for (int m : {1, 2, 5}) {
      const double e = m * std::pow(10.0, d);
      if (std::log10(e) > le1 + 1e-9) break;
      const double y = Y(e);
      svg += Format("<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"%s\"/>\n", left,
                    y, left + plotW, y, m == 1 ? "#bbb" : "#eee");
      if (m == 1)
        svg += Format("<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"end\">%s</text>\n", left - 6,
                      y + 4, Pct(e, 2).c_str());
    }
  }
  svg += Format(
      "<rect x=\"%.1f\" y=\"%.1f\" width=\"%.1f\" height=\"%.1f\" fill=\"none\" "
      "stroke=\"#333\"/>\n",
      left, top, plotW, plotH);
  svg += Format(
      "<text x=\"%.1f\" y=\"%.1f\" text-anchor=\"middle\">bake time, CPU seconds at 1 "
      "thread (log)</text>\n",
      left + plotW / 2, height - 18);
  svg += Format(
      "<text transform=\"translate(18 %.1f) rotate(-90)\" text-anchor=\"middle\">mean "
      "relative irradiance error (log)</text>\n",
      top + plotH / 2);

  // Ladder curves.
  std::vector<std::string> configs;
  std::map<std::string, std::string> labels;
  for (const BakeRow& row : r.rows) {
    if (row.scene != scene || row.group != "ladder") continue;
    if (std::find(configs.begin(), configs.end(), row.config) == configs.end())
      configs.push_back(row.config);
    labels[row.config] = row.label;
  }
  double legendY = top + 8;
  const double legendX = left + plotW + 20;
  for (size_t c = 0; c < configs.size(); ++c) {
    const char* colour = kColours[c % 10];
    const std::vector<Point> curve = Curve(r, scene, configs[c]);
    std::string points;
    for (const Point& p : curve)
      if (p.time > 0 && p.error > 0) points += Format("%.1f,%.1f ", X(p.time), Y(p.error));
    svg += Format("<polyline points=\"%s\" fill=\"none\" stroke=\"%s\" stroke-width=\"2\"/>\n",
                  points.c_str(), colour);
    for (const Point& p : curve)
      if (p.time > 0 && p.error > 0)
        svg += Format("<circle cx=\"%.1f\" cy=\"%.1f\" r=\"3\" fill=\"%s\"/>\n", X(p.time),
                      Y(p.error), colour);
    svg += Format(
        "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"%s\" "
        "stroke-width=\"2\"/><text x=\"%.1f\" y=\"%.1f\">%s</text>\n",
        legendX, legendY, legendX + 22, legendY, colour, legendX + 28, legendY + 4,
        Escape(labels[configs[c]]).c_str());
    legendY += 18;
  }
  svg +=
      Format("<text x=\"%.1f\" y=\"%.1f\" fill=\"#555\">dots: 16, 32, ... samples/probe</text>\n",
             legendX, legendY + 4);
  legendY += 26;
  // Adaptive (squares) and presets (diamonds), labelled.
  for (const BakeRow& row : r.rows) {
    if (row.scene != scene || (row.group != "preset" && row.group != "adaptive")) continue;
    if (!(row.cpuSeconds > 0) || !(row.error.meanIrradianceRel > 0)) continue;
    const double x = X(row.cpuSeconds), y = Y(row.error.meanIrradianceRel);
    if (row.group == "preset") {
      svg += Format("<path d=\"M %.1f %.1f l 6 6 l -6 6 l -6 -6 z\" fill=\"black\"/>\n", x, y - 6);
      svg += Format("<text x=\"%.1f\" y=\"%.1f\" font-weight=\"bold\">%s</text>\n", x + 8, y - 6,
                    Escape(row.label).c_str());
    } else {
      svg += Format(
          "<rect x=\"%.1f\" y=\"%.1f\" width=\"7\" height=\"7\" fill=\"none\" "
          "stroke=\"%s\" stroke-width=\"1.5\"/>\n",
          x - 3.5, y - 3.5, row.batches == 64 ? "#2ca02c" : "#444");
    }
  }
  svg += Format(
      "<path d=\"M %.1f %.1f l 6 6 l -6 6 l -6 -6 z\" fill=\"black\"/><text x=\"%.1f\" "
      "y=\"%.1f\">quality presets (vs the deep reference)</text>\n",
      legendX + 11, legendY - 6, legendX + 28, legendY + 4);
  legendY += 18;
  svg += Format(
      "<rect x=\"%.1f\" y=\"%.1f\" width=\"7\" height=\"7\" fill=\"none\" stroke=\"#444\" "
      "stroke-width=\"1.5\"/><text x=\"%.1f\" y=\"%.1f\">adaptive, 16 batches</text>\n",
      legendX + 7.5, legendY - 3.5, legendX + 28, legendY + 4);
  legendY += 18;
  svg += Format(
      "<rect x=\"%.1f\" y=\"%.1f\" width=\"7\" height=\"7\" fill=\"none\" "
      "stroke=\"#2ca02c\" stroke-width=\"1.5\"/><text x=\"%.1f\" y=\"%.1f\">adaptive, "
      "64 batches (default)</text>\n",
      legendX + 7.5, legendY - 3.5, legendX + 28, legendY + 4);
  svg += "</svg>\n";
  return svg;
}

// ---- markdown ----

std::vector<std::string> Configs(const BenchResults& r, const std::string& scene,
                                 const std::string& group) {
  std::vector<std::string> out;
  for (const BakeRow& row : r.rows)
    if (row.scene == scene && row.group == group &&
        std::find(out.begin(), out.end(), row.config) == out.end())
      out.push_back(row.config);
  return out;
}

std::string Label(const BenchResults& r, const std::string& config) {
  for (const BakeRow& row : r.rows)
    if (row.config == config) return row.label;
  return config;
}

// Least-squares slope of log(error) against log(samples) over the ladder points with at least
// 64 samples (-0.5 is the Monte Carlo rate).
double ErrorSlope(const BenchResults& r, const std::string& scene, const std::string& config) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int n = 0;
  for (const BakeRow& row : r.rows) {
    if (row.scene != scene || row.config != config || row.group != "ladder") continue;
    if (row.samplesPerProbe < 64 || !(row.error.meanIrradianceRel > 0)) continue;
    const double x = std::log(double(row.samplesPerProbe)),
                 y = std::log(row.error.meanIrradianceRel);
    sx += x, sy += y, sxx += x * x, sxy += x * y;
    ++n;
  }
  if (n < 2) return std::numeric_limits<double>::quiet_NaN();
  return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

const BakeRow* FindRow(const BenchResults& r, const std::string& scene, const std::string& config,
                       int64_t samples = -1) {
  const BakeRow* found = nullptr;
  for (const BakeRow& row : r.rows)
    if (row.scene == scene && row.config == config &&
        (samples < 0 || row.samplesPerProbe == samples))
      found = &row;
  return found;
}

// Time ratio of config b over config a to reach each error level (a faster when > 1).
std::string SpeedupLine(const BenchResults& r, const std::string& scene, const std::string& slow,
                        const std::string& fast) {
  const std::vector<Point> s = Curve(r, scene, slow), f = Curve(r, scene, fast);
  std::string out;
  for (double e : kErrorLevels) {
    const TimeTo ts = TimeToError(s, e), tf = TimeToError(f, e);
    if (ts.how == Reach::kNone || tf.how == Reach::kNone) continue;
    if (ts.how == Reach::kBelowAtFirst || tf.how == Reach::kBelowAtFirst) continue;
    const bool approx = ts.how == Reach::kExtrapolated || tf.how == Reach::kExtrapolated;
    out += Format("%s%s: %s%.2gx; ", out.empty() ? "" : "", Pct(e, 2).c_str(), approx ? "~" : "",
                  ts.time / tf.time);
  }
  if (!out.empty()) out.resize(out.size() - 2);
  return out;
}

// Where `fast` overtakes `slow`: scanning a fine log grid of errors from the larger of the two
// curves' first errors down to the smaller of their last ones (times past a curve's last point
// extrapolated with error ~ t^-1/2), the largest error below which `fast` always needs less time.
std::string CrossingText(const BenchResults& r, const std::string& scene, const std::string& slow,
                         const std::string& fast) {
  const std::vector<Point> s = Curve(r, scene, slow), f = Curve(r, scene, fast);
  if (s.empty() || f.empty()) return "not measured";
  const double hi = std::max(s.front().error, f.front().error);
  const double lo = std::min(s.back().error, f.back().error);
  double beatsBelow = -1;
  bool everywhere = true;
  for (int k = 0; k <= 400; ++k) {
    const double e = std::exp(std::log(hi) + (std::log(lo) - std::log(hi)) * k / 400.0);
    const TimeTo ts = TimeToError(s, e), tf = TimeToError(f, e);
    // Both already below e at their first point: no comparison at this error.
    if (ts.how == Reach::kBelowAtFirst && tf.how == Reach::kBelowAtFirst) continue;
    if (tf.time < ts.time) {
      if (beatsBelow < 0) beatsBelow = e;
    } else {
      everywhere = false;
      beatsBelow = -1;
    }
  }
  if (everywhere)
    return Format("faster at every error from %s down to %s", Pct(hi, 3).c_str(),
                  Pct(lo, 3).c_str());
  if (beatsBelow < 0) return Format("not faster at %s", Pct(lo, 3).c_str());
  return Format("faster for every error below %s (scanned %s down to %s)",
                Pct(beatsBelow, 3).c_str(), Pct(hi, 3).c_str(), Pct(lo, 3).c_str());
}

std::string Markdown(const BenchResults& r) {
  std::string md;
  md += "# probebake: accuracy and speed benchmark\n\n";
  md += Format(
      "Generated by `scripts/bench.sh%s` (tool: `probebake-bench`, tests/bench) on %s, host `%s`, "
      "%d hardware threads; %s. Load average %.2f at the start, %.2f at the end (other work ran "
      "on the machine: times are CPU seconds of the bake itself, minimum over repeats, which "
      "other processes inflate far less than wall time). Whole run: %.0f s.\n\n",
      r.quick ? " --quick" : "", r.date.c_str(), r.host.c_str(), r.hardwareThreads,
      r.generator.c_str(), r.loadStart, r.loadEnd, r.totalSeconds);
  md +=
      "Every bake runs on one thread; its time includes everything `Bake` does (BVH build, "
      "placement and validity rays, light tables, sampling). Errors are per probe, "
      "then averaged over probes: the relative L2 error of the reconstructed irradiance over "
      "the sphere of normals (quadrature), the relative L2 error of the radiance SH "
      "coefficients, and the relative error of the luminance of L0. The bake reports "
      "`std_error`, its estimate of the relative error of its luminance irradiance over the "
      "sphere of normals, and `std_error_l0`, of the luminance of L0. **Honesty** = RMS "
      "measured luminance irradiance error / RMS `std_error` (combined with the reference's "
      "own), **honesty L0** the same for L0 and `std_error_l0`, **honesty RGB** the RGB "
      "irradiance error against the one predicted from the per-coefficient standard errors: ~1 "
      "is honest, > 1 means the bake underestimates its error. "
      "The reference is truncated to each bake's order, so the figures measure the "
      "estimator, not SH truncation.\n\n";
  md += "Current presets: " + r.presetText + ".\n\n";

  // ---- summary ----
  md += "## Summary\n\n";
  for (const SceneInfo& sc : r.scenes) {
    const std::vector<Point> naive = Curve(r, sc.name, "naive"),
                             best = Curve(r, sc.name, "nee_mis_sobol");
    if (naive.empty() || best.empty()) continue;
    std::string factors;
    for (double e : {0.1, 0.05}) {
      const TimeTo a = TimeToError(naive, e), b = TimeToError(best, e);
      if (a.how == Reach::kNone || b.how == Reach::kNone) continue;
      factors += Format("%s%s%.3gx at %s", factors.empty() ? "" : ", ",
                        (a.how == Reach::kExtrapolated || b.how == Reach::kExtrapolated) ? "~" : "",
                        a.time / b.time, Pct(e, 2).c_str());
    }
    md += Format(
        "- **%s**: NEE+MIS with Sobol vs the naive estimator: %s; less time to equal error "
        "by %s. Error slope vs samples (NEE+MIS Sobol): %.2f.\n",
        sc.name.c_str(), CrossingText(r, sc.name, "naive", "nee_mis_sobol").c_str(),
        factors.c_str(), ErrorSlope(r, sc.name, "nee_mis_sobol"));
  }
  {
    std::vector<double> honesty;
    for (const BakeRow& row : r.rows)
      if (row.group == "ladder" && row.config != "naive") honesty.push_back(row.error.honesty);
    if (!honesty.empty())
      md += Format(
          "- Error estimate: honesty (measured / reported irradiance error) median %.2f, range "
          "%.2f to %.2f over every non-naive ladder bake; the naive estimator's is "
          "not honest (see below).\n",
          Median(honesty), *std::min_element(honesty.begin(), honesty.end()),
          *std::max_element(honesty.begin(), honesty.end()));
  }
  for (const ThroughputInfo& tp : r.throughput) {
    const RawRate* raw = tp.raw.Find("probe random", "rtcIntersect1", 1);
    const double samplingCpu = tp.bakeCpuSeconds - tp.setupCpuSeconds;
    const double samplingMrays = double(tp.rays - tp.setupRays) / samplingCpu * 1e-6;
    md += Format(
        "- Throughput, %s: %.3g Mrays/CPU-s, %.2f of raw rtcIntersect1 probe rays "
        "(%.2f in the sampling phase); back-to-back pairs of the two: %s.\n",
        tp.scene.c_str(), tp.tracerCpuMrays, tp.tracerCpuMrays / raw->cpuMraysPerSecond,
        samplingMrays / raw->cpuMraysPerSecond, PairedText(tp.pairedFractions).c_str());
  }
  if (const std::optional<ScalingBest> best = BestOf(r.scaling)) {
    const auto [w1, w2, c1, c2] = *best;
    md += Format(
        "- Scaling (demo): %.2fx probes/s from 1 to 2 threads; a perfectly parallel raw "
        "Embree loop reached %.2fx at the same time (load average %.2f), so the bake scales at "
        "%.2f of the achievable. CPUs kept busy, 2 threads against 1: %.2fx (below 2 only when "
        "threads wait; it holds where the CPUs' speeds differ, which moves the first figure).\n",
        w1 / w2, r.scaling.rawRatio, r.scaling.load,
        r.scaling.rawRatio > 0 ? (w1 / w2) / r.scaling.rawRatio : 0.0, (w1 / w2) * (c2 / c1));
  }
  if (r.memory.measured)
    md += Format(
        "- Memory: dense %lld-probe order-2 bake peaks at %.2fx its SH data; .vdb %.0f "
        "MiB.\n",
        (long long)r.memory.probes, double(r.memory.peakBake) / double(r.memory.shBytes),
        r.memory.vdbBytes / kMiB);

  // ---- presets ----
  md += "\n## Which preset\n\n";
  for (const char* preset : {"PREVIEW", "PRODUCTION", "REFERENCE"}) {
    std::string line;
    for (const SceneInfo& sc : r.scenes) {
      const BakeRow* row = FindRow(r, sc.name, std::string("preset_") + preset);
      if (!row) continue;
      line += Format("%s%s %s in %.2g ms/probe", line.empty() ? "" : "; ", sc.name.c_str(),
                     Pct(row->error.meanIrradianceRel).c_str(),
                     1e3 * row->cpuSeconds / double(std::max<int64_t>(row->probes, 1)));
    }
    const BakeRow* any = nullptr;
    for (const SceneInfo& sc : r.scenes)
      if (!any) any = FindRow(r, sc.name, std::string("preset_") + preset);
    if (!any) continue;
    const char* use =
        std::string(preset) == "PREVIEW"
            ? "iterating on lighting and probe placement: the error is visible noise, but the "
              "overall light levels and colours are right"
        : std::string(preset) == "PRODUCTION"
            ? "shipping bakes: the noise left is a few percent on hard interiors (sun "
              "patches seen through a window) and lower elsewhere"
            : "ground truth for comparisons, regression baselines and tuning other "
              "settings";
    md += Format(
        "- **%s** (%lld samples, depth %d, target %g): %s. Mean irradiance error and CPU "
        "time per probe on one core: %s.\n",
        preset, (long long)any->samplesPerProbe, any->maxDepth, any->targetRelError, use,
        line.c_str());
  }
  md +=
      "- Explicit numbers: error falls as samples^slope (slopes in the summary, ~-0.5), so "
      "quartering the error costs 16x the samples; depth beyond 8 is nearly free (see Path "
      "depth) and below 6 loses visible light indoors. Adaptive sampling pays with many "
      "batches, hence its default of 64 (see Adaptive sampling).\n\n";

  md +=
      "## Scenes and references\n\n| scene | what | triangles | probes (grid / baked) | "
      "reference | depth-8 bias |\n|---|---|---|---|---|---|\n";
  for (const SceneInfo& s : r.scenes) {
    md += Format("| %s | %s | %lld | %lld / %lld | %s | %s |\n", s.name.c_str(),
                 s.description.c_str(), (long long)s.triangles, (long long)s.gridProbes,
                 (long long)s.bakedProbes, s.referenceText.c_str(),
                 s.depthBiasIrradiance >= 0 ? Pct(s.depthBiasIrradiance).c_str() : "none");
  }
  md +=
      "\nThe depth-8 bias is the mean relative irradiance difference between the depth-8 "
      "reference and the depth-64 one: the light a depth-8 bake leaves out by design. Ladder "
      "and adaptive bakes (depth 8) are compared with the same-depth reference; the presets "
      "(their own depths) with the deep one, so their errors include their depth's bias.\n\n";

  for (const SceneInfo& s : r.scenes) {
    md += "## " + s.name + "\n\n";
    md += Format("![error vs time, %s](error_vs_time_%s.svg)\n\n", s.name.c_str(), s.name.c_str());
    md +=
        "Time to reach a mean relative irradiance error (CPU s at 1 thread; `~` extrapolated "
        "past the ladder with error ~ t^-1/2, `<=` already reached at 16 samples):\n\n";
    md += "| configuration |";
    // (Appended piecewise: GCC 12 warns falsely (-Wrestrict) on " " + std::string.)
    for (double e : kErrorLevels) md += Format(" %s |", Pct(e, 2).c_str());
    md += " error slope vs samples |\n|---|";
    for (size_t i = 0; i <= std::size(kErrorLevels); ++i) md += "---|";
    md += "\n";
    for (const std::string& c : Configs(r, s.name, "ladder")) {
      md += "| " + Label(r, c) + " |";
      const std::vector<Point> curve = Curve(r, s.name, c);
      for (double e : kErrorLevels) md += Format(" %s |", TimeText(TimeToError(curve, e)).c_str());
      md += Format(" %.2f |\n", ErrorSlope(r, s.name, c));
    }
    md += "\nSpeed-ups (time of the first / time of the second, at equal error):\n\n";
    md += "- NEE+MIS Sobol vs naive: " + SpeedupLine(r, s.name, "naive", "nee_mis_sobol") +
          ". NEE+MIS Sobol: " + CrossingText(r, s.name, "naive", "nee_mis_sobol") + ".\n";
    md += "- NEE+MIS vs NEE only (both Sobol): " +
          SpeedupLine(r, s.name, "nee_sobol", "nee_mis_sobol") + ".\n";
    md += "- Sobol vs independent (NEE+MIS): " +
          SpeedupLine(r, s.name, "nee_mis_independent", "nee_mis_sobol") + ".\n";
    md += "- Russian roulette on vs off: " +
          SpeedupLine(r, s.name, "nee_mis_sobol_no_rr", "nee_mis_sobol") + ".\n\n";

    md +=
        "| configuration | samples | CPU s | wall s | Mrays/CPU-s | probes/s | irradiance err "
        "mean | median | max | radiance err | L0 err RMS | mean std_error | honesty | honesty L0 "
        "| honesty RGB |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const BakeRow& row : r.rows) {
      if (row.scene != s.name || row.group != "ladder") continue;
      md += Format(
          "| %s | %lld | %.3g | %.3g | %.3g | %.3g | %s | %s | %s | %s | %s | %s | %s | %s | "
          "%s |\n",
          row.label.c_str(), (long long)row.samplesPerProbe, row.cpuSeconds, row.wallSeconds,
          double(row.rays) / row.cpuSeconds * 1e-6, double(row.probes) / row.wallSeconds,
          Pct(row.error.meanIrradianceRel).c_str(), Pct(row.error.medianIrradianceRel).c_str(),
          Pct(row.error.maxIrradianceRel).c_str(), Pct(row.error.meanRadianceRel).c_str(),
          Pct(row.error.rmsL0Rel).c_str(), Pct(row.error.meanStdError).c_str(),
          Num(row.error.honesty).c_str(), Num(row.error.honestyL0).c_str(),
          Num(row.error.honestyIrradiance).c_str());
    }
    md += "\n";
  }

  md +=
      "## Notes on the curves\n\n"
      "- The naive estimator finds small bright sources only by hitting them: a ray from a "
      "demo probe hits the 0.53-degree sun with probability ~5e-6, and each hit adds ~2e5 "
      "times the sun's share to one sample. Until a batch has hit it, the estimate is low and "
      "its batch spread is small, so its error looks moderate and its std_error is far too "
      "small (honesty >> 1); once a probe hits it, its error jumps (the spikes of the naive "
      "curves). The mean over probes of these heavy-tailed errors is the headline figure; "
      "the median column shows the typical probe. Time-to-error for the naive estimator is "
      "extrapolated from its last point with error ~ t^-1/2.\n"
      "- Each SH order is compared with the reference truncated to that order, so order 1 "
      "shows a lower error than order 2 at the same samples (no band-2 noise) while its "
      "truncation error, not measured here, is larger. Order 3 has the irradiance error of "
      "order 2 (the clamped cosine has no band-3 term) and a higher radiance error.\n"
      "- Russian roulette leaves the error per sample nearly unchanged and cuts rays per "
      "sample where paths are long (indoors); the sky_sphere scene has no bounces at all.\n"
      "- The Sobol sampler (the default) stratifies within each batch: the probe's directions "
      "and light points are a spherical Fibonacci set turned by a random rotation of the "
      "batch's own, the path's later numbers an Owen-scrambled Sobol sequence of its own, so "
      "the batch spread stays an honest error estimate. Its default of 4 batches keeps each "
      "batch's set large. A slope below -0.5 means it beats plain Monte Carlo's rate.\n\n";
  md +=
      "## Is the error estimate honest?\n\nMedian over the ladder of each configuration's "
      "honesty ratios (16 ... max samples), as median (min, max):\n\n| scene | configuration | "
      "honesty (std_error) | honesty L0 (std_error_l0) | honesty RGB |\n|---|---|---|---|---|\n";
  const auto spread = [](const std::vector<double>& v) {
    return Format("%.2f (%.2f, %.2f)", Median(v), *std::min_element(v.begin(), v.end()),
                  *std::max_element(v.begin(), v.end()));
  };
  for (const SceneInfo& s : r.scenes) {
    for (const std::string& c : Configs(r, s.name, "ladder")) {
      std::vector<double> h, l0, irr;
      for (const BakeRow& row : r.rows)
        if (row.scene == s.name && row.config == c && row.group == "ladder") {
          h.push_back(row.error.honesty);
          l0.push_back(row.error.honestyL0);
          irr.push_back(row.error.honestyIrradiance);
        }
      if (l0.empty()) continue;
      md += Format("| %s | %s | %s | %s | %s |\n", s.name.c_str(), Label(r, c).c_str(),
                   spread(h).c_str(), spread(l0).c_str(), spread(irr).c_str());
    }
  }

  md +=
      "\n## Adaptive sampling\n\n`targetRelError` is a standard error (a 1-sigma figure), so a "
      "probe whose estimate is honest misses it ~32% of the time by chance; it bounds "
      "`std_error`, so the target is met when the RMS over the probes of the measured luminance "
      "irradiance errors is at or below it. Cap = "
      "largest ladder count; probes that reach it stop there whatever their error, so the last "
      "column judges the target on the probes that stopped because of it. A probe samples at "
      "least 8 of its batches, then 2 more, before it may stop (bake.cpp kMinAdaptiveBatches): "
      "with 16 batches that is 10/16 of the cap, with the adaptive default of 64 10/64. It stops "
      "when an upper confidence bound of its error, not the estimate itself, is under the "
      "target at two successive rounds (bake.h AdaptiveErrorBound).\n\n| scene | target | batches "
      "| mean samples | "
      "CPU s | RMS measured | RMS / target | met | stopped by target | measured <= target | "
      "<= 2 target | irradiance err | RMS / target, probes stopped by target |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const BakeRow& row : r.rows) {
    if (row.group != "adaptive") continue;
    const double ratio = row.error.rmsIrradianceLumRel / row.targetRelError;
    md +=
        Format("| %s | %s | %d | %.0f | %.3g | %s | %.2f | %s | %s | %s | %s | %s | %s |\n",
               row.scene.c_str(), Pct(row.targetRelError, 2).c_str(), row.batches,
               row.error.meanSamples, row.cpuSeconds, Pct(row.error.rmsIrradianceLumRel).c_str(),
               ratio, ratio <= 1 ? "yes" : "**no**", Pct(row.stoppedByTarget, 3).c_str(),
               Pct(row.measuredWithinTarget, 3).c_str(), Pct(row.measuredWithin2Target, 3).c_str(),
               Pct(row.error.meanIrradianceRel).c_str(),
               row.stoppedByTarget > 0 ? Format("%.2f", row.stoppedRmsOverTarget).c_str() : "-");
  }
  md +=
      "\nPer-probe figures (target, samples, reported and measured error): "
      "`adaptive_probes.csv`.\n";

  md +=
      "\n## Quality presets\n\nEach preset's own numbers (samples, depth, target), against the "
      "deep (depth-64) reference, so depth truncation counts as error.\n\n| scene | preset | "
      "samples cap | depth | target | mean samples | CPU s | ms/probe | irradiance err mean | "
      "radiance err | L0 err RMS | mean std_error | L0 bias (mean signed +- its std error) |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const BakeRow& row : r.rows) {
    if (row.group != "preset") continue;
    md += Format(
        "| %s | %s | %lld | %d | %g | %.0f | %.3g | %.3g | %s | %s | %s | %s | %+.2f%% "
        "+- %.2f%% |\n",
        row.scene.c_str(), row.label.c_str(), (long long)row.samplesPerProbe, row.maxDepth,
        row.targetRelError, row.error.meanSamples, row.cpuSeconds,
        1e3 * row.cpuSeconds / double(std::max<int64_t>(row.probes, 1)),
        Pct(row.error.meanIrradianceRel).c_str(), Pct(row.error.meanRadianceRel).c_str(),
        Pct(row.error.rmsL0Rel).c_str(), Pct(row.error.meanStdError).c_str(),
        100 * row.error.meanSignedL0, 100 * row.error.meanSignedL0StdError);
  }

  md +=
      "\n## Path depth\n\nThe largest ladder count at several maximum depths, against the "
      "deep (depth-64) reference. Light reflected more times than the depth is left out, so a "
      "low depth shows as a negative L0 bias; the bias is resolved far below the per-probe "
      "noise because noise averages out over the probes and bias does not.\n\n| scene | "
      "depth | CPU s | rays/sample | irradiance err mean | L0 err RMS | L0 bias (mean signed +- "
      "its std error) |\n|---|---|---|---|---|---|---|\n";
  for (const BakeRow& row : r.rows) {
    if (row.group != "depth") continue;
    md += Format("| %s | %d | %.3g | %.2f | %s | %s | %+.2f%% +- %.2f%% |\n", row.scene.c_str(),
                 row.maxDepth, row.cpuSeconds,
                 double(row.rays) / double(std::max<int64_t>(row.samples, 1)),
                 Pct(row.error.meanIrradianceRel).c_str(), Pct(row.error.rmsL0Rel).c_str(),
                 100 * row.error.meanSignedL0, 100 * row.error.meanSignedL0StdError);
  }

  md +=
      "\n## Throughput against raw Embree\n\nThe tracer's rays (every ray, shadow rays "
      "included) per CPU second at 1 thread, default settings, against raw Embree tracing the "
      "same scene's probe rays from the same probes (rtcIntersect1, random directions): "
      "\"fraction\". The whole bake includes its fixed cost (BVH build, light tables, "
      "placement and 128 validity rays per probe, measured as a bake of one sample per probe); "
      "the sampling phase is the bake minus that. \"Embree share\" is the CPU time raw Embree "
      "needs for the bake's own ray mix (first-hit and validity rays at the probe-ray rate, "
      "continuation rays at the bounce rate, shadow rays at the rtcOccluded1 rate) over the "
      "bake's CPU time: the fraction of the bake spent in Embree if Embree ran as fast as it "
      "does alone. \"Paired\": the same fraction from a tracer bake and a raw Embree reading taken "
      "right after it, repeated; the median and range of those ratios, steadier on a shared "
      "machine than the columns before it, whose halves were measured minutes apart.\n\n| scene | "
      "triangles | samples/probe | rays (intersect / shadow) | bake "
      "CPU s (setup) | tracer Mrays/CPU-s (sampling phase) | raw probe rays Mrays/CPU-s | "
      "fraction, whole bake (sampling phase) | fraction, paired | Embree share, whole bake "
      "(sampling phase) |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const ThroughputInfo& tp : r.throughput) {
    const RawRate* raw = tp.raw.Find("probe random", "rtcIntersect1", 1);
    const double samplingCpu = tp.bakeCpuSeconds - tp.setupCpuSeconds;
    const double samplingMrays = double(tp.rays - tp.setupRays) / samplingCpu * 1e-6;
    md += Format(
        "| %s | %lld | %lld | %lld / %lld | %.3g (%.3g) | %.3g (%.3g) | %.3g | %.2f "
        "(%.2f) | %s | %.2f (%.2f) |\n",
        tp.scene.c_str(), (long long)tp.raw.triangles,
        (long long)(tp.samples / std::max<int64_t>(tp.raw.probes, 1)), (long long)tp.intersectRays,
        (long long)tp.shadowRays, tp.bakeCpuSeconds, tp.setupCpuSeconds, tp.tracerCpuMrays,
        samplingMrays, raw->cpuMraysPerSecond, tp.tracerCpuMrays / raw->cpuMraysPerSecond,
        samplingMrays / raw->cpuMraysPerSecond, PairedText(tp.pairedFractions).c_str(),
        tp.embreeOnlySeconds / tp.bakeCpuSeconds, tp.embreeOnlySamplingSeconds / samplingCpu);
  }
  // In run order, with the CPU of each: a shared VM's vCPU that slows down mid-run slows the
  // bake more than raw Embree, so its pairs read low together and pairing cannot cancel it.
  md += "\nPaired fractions in run order (the CPU each pair ran on):\n\n";
  for (const ThroughputInfo& tp : r.throughput) {
    md += "- " + tp.scene + ":";
    for (size_t k = 0; k < tp.pairedFractions.size(); ++k) {
      const int cpu = tp.pairedCpus[k];
      md += Format(" %.2f (%s)", tp.pairedFractions[k],
                   cpu >= 0 ? Format("CPU %d", cpu).c_str() : "unpinned");
    }
    md += "\n";
  }
  md +=
      "\nRaw Embree, Mrays/s (per wall second at 1 and 2 threads; per CPU second of the tracing "
      "threads in brackets):\n\n| scene | rays | API | 1 thread | 2 threads |\n|---|---|---|---|"
      "---|\n";
  for (const ThroughputInfo& tp : r.throughput) {
    for (const RawRate& one : tp.raw.rates) {
      if (one.threads != 1) continue;
      const RawRate* two = tp.raw.Find(one.rays, one.api, 2);
      md += Format(
          "| %s | %s | %s | %.3g (%.3g) | %s |\n", tp.scene.c_str(), one.rays.c_str(),
          one.api.c_str(), one.wallMraysPerSecond, one.cpuMraysPerSecond,
          two ? Format("%.3g (%.3g)", two->wallMraysPerSecond, two->cpuMraysPerSecond).c_str()
              : "-");
    }
  }

  md += ReplayMarkdown(r);

  md += "\n## Scaling\n\n";
  if (const std::optional<ScalingBest> best = BestOf(r.scaling)) {
    const ScalingInfo& sc = r.scaling;
    const auto [w1, w2, c1, c2] = *best;
    md += Format(
        "%s scene, %lld samples/probe, %lld probes, interleaved 1- and 2-thread bakes (%zu "
        "each; bits identical between them), load average %.2f when it started.\n\n| threads | "
        "wall s (min) | probes/s | CPU s (min) |\n|---|---|---|---|\n| 1 | %.3g | %.3g | %.3g |\n"
        "| 2 | %.3g | %.3g | %.3g |\n\nRatio of probes/s, 2 threads / 1 thread: **%.2fx** "
        "(CPU time grows by %.2fx from 1 to 2 threads: the work itself does not grow, so a ratio "
        "below 2 comes from waiting, not from extra work; the CPUs kept busy, the product of the "
        "two, "
        "%.2fx, is what waiting lowers, whatever the CPUs' speeds). Control: raw Embree's own 2/1 "
        "thread "
        "ratio on the same probes, measured right after: %.2fx, so the bake reaches %.2f of what "
        "a perfectly parallel loop reached under the same load. On a shared machine both are "
        "capped by the other work (with k other busy threads on 2 cores, 1 thread gets "
        "min(1, 2/(k+1)) of a core and 2 threads 4/(k+2)); only an idle machine shows the "
        "absolute ratio.\n",
        sc.scene.c_str(), (long long)sc.samplesPerProbe, (long long)sc.probes, sc.wall1.size(),
        sc.load, w1, double(sc.probes) / w1, c1, w2, double(sc.probes) / w2, c2, w1 / w2, c2 / c1,
        (w1 / w2) * (c2 / c1), sc.rawRatio, sc.rawRatio > 0 ? (w1 / w2) / sc.rawRatio : 0.0);
  } else {
    md += "Not measured.\n";
  }

  md += "\n## Many lights\n\n";
  if (!r.manyLights.empty()) {
    const ManyLightsRow& first = r.manyLights.front();
    md += Format(
        "The demo room with its ceiling light replaced by N lights, %lld samples/probe, %lld "
        "probes, 1 thread. **ceiling**: N small (0.1 m) rects scattered over the ceiling with the "
        "ceiling light's total power. **volume**: N point, spot, rect and sphere lights (a quarter "
        "each) scattered through the room. Lights are chosen linearly below %zu of a kind (area, "
        "or point and spot) and through a light tree from there. Efficiency is 1 / (CPU time x "
        "mean std_error^2), relative to the layout's first row: above 1 means less noise per "
        "second.\n\n| layout | lights | chosen through a tree | CPU s | ms/probe | mean "
        "std_error | efficiency |\n|---|---|---|---|---|---|---|\n",
        (long long)first.samplesPerProbe, (long long)first.probes, kLightTreeMinLights);
    const ManyLightsRow* base = nullptr;
    for (const ManyLightsRow& row : r.manyLights) {
      if (!base || base->layout != row.layout) base = &row;
      const double eff = (base->cpu * base->meanStdError * base->meanStdError) /
                         (row.cpu * row.meanStdError * row.meanStdError);
      md +=
          Format("| %s | %d | %zu | %.3g | %.3g | %s | %.2f |\n", row.layout.c_str(), row.lights,
                 row.treeLights, row.cpu, 1e3 * row.cpu / double(std::max<int64_t>(row.probes, 1)),
                 Pct(row.meanStdError).c_str(), eff);
    }
  } else {
    md += "Not measured.\n";
  }

  md += "\n## Memory\n\n";
  const MemoryInfo& m = r.memory;
  if (m.measured) {
    md += Format(
        "A dense %lld-probe order-2 bake with irradiance (sky_sphere scene, %lld samples/probe, "
        "placement ALL, all threads) in a child process: bake %.1f s.\n\n| figure | MiB |\n|---|"
        "---|\n| SH data (radiance + irradiance planes, float RGB) | %.1f |\n| whole ProbeVolume "
        "(+ validity, std_error, sample_count, active) | %.1f |\n| process before the job | %.1f |"
        "\n| peak RSS of the bake (VmHWM) | %.1f |\n| peak RSS / SH data | **%.2fx** |\n| (peak - "
        "process before) / SH data | %.2fx |\n| extra peak while writing the .vdb | %s |\n| .vdb "
        "file | %.1f (written in %.1f s) |\n",
        (long long)m.probes, (long long)m.samplesPerProbe, m.bakeSeconds, m.shBytes / kMiB,
        m.volumeBytes / kMiB, m.baselineRss / kMiB, m.peakBake / kMiB,
        double(m.peakBake) / double(m.shBytes),
        double(m.peakBake - m.baselineRss) / double(m.shBytes),
        m.peakWriteExtra >= 0 ? Num(m.peakWriteExtra / kMiB, 3).c_str() : "unknown",
        m.vdbBytes / kMiB, m.writeSeconds);
  } else {
    md += m.note + "\n";
  }

  md +=
      "\n## Adaptive, preset and depth rows in full\n\n| scene | configuration | samples cap | "
      "depth | "
      "CPU s | wall s | irradiance err mean | radiance err | L0 err RMS | mean std_error | "
      "honesty L0 | honesty irr | mean samples |\n|---|---|---|---|---|---|---|---|---|---|---|"
      "---|---|\n";
  for (const BakeRow& row : r.rows) {
    if (row.group == "ladder") continue;
    md += Format("| %s | %s | %lld | %d | %.3g | %.3g | %s | %s | %s | %s | %s | %s | %.0f |\n",
                 row.scene.c_str(), row.label.c_str(), (long long)row.samplesPerProbe, row.maxDepth,
                 row.cpuSeconds, row.wallSeconds, Pct(row.error.meanIrradianceRel).c_str(),
                 Pct(row.error.meanRadianceRel).c_str(), Pct(row.error.rmsL0Rel).c_str(),
                 Pct(row.error.meanStdError).c_str(), Num(row.error.honestyL0).c_str(),
                 Num(row.error.honestyIrradiance).c_str(), row.error.meanSamples);
  }
  bool allIdentical = true;
  for (const BakeRow& row : r.rows) allIdentical = allIdentical && row.repeatsIdentical;
  md += Format("\nRepeated bakes gave identical bits: %s.\n", allIdentical ? "yes" : "**NO**");
  return md;
}

// ---- CSV / JSON ----

std::string Csv(const BenchResults& r) {
  std::string csv =
      "scene,config,group,reference,samples_per_probe,target_rel_error,sh_order,max_depth,"
      "batches,estimator,sampler,russian_roulette,threads,wall_s,cpu_s,rays,samples,probes,"
      "mrays_per_cpu_s,probes_per_wall_s,irr_err_mean,irr_err_median,irr_err_max,irr_err_rms,"
      "rad_err_mean,l0_err_rms,irr_lum_err_rms,std_error_mean,std_error_rms,std_error_l0_mean,"
      "honesty,honesty_l0,honesty_irr,"
      "mean_samples,ref_irr_err_mean,ref_std_error_mean,stopped_by_target,"
      "measured_within_target,measured_within_2target,stopped_rms_over_target,mean_signed_l0,"
      "mean_signed_l0_std_error,repeats_identical\n";
  for (const BakeRow& w : r.rows) {
    const ErrorSummary& e = w.error;
    csv += Format(
        "%s,%s,%s,%s,%lld,%g,%d,%d,%d,%s,%s,%d,%d,%.6g,%.6g,%lld,%lld,%lld,%.6g,%.6g,%.6g,%.6g,"
        "%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,"
        "%.6g,%.6g,%.6g,%d\n",
        w.scene.c_str(), w.config.c_str(), w.group.c_str(), w.reference.c_str(),
        (long long)w.samplesPerProbe, w.targetRelError, w.shOrder, w.maxDepth, w.batches,
        w.estimator.c_str(), w.sampler.c_str(), w.russianRoulette ? 1 : 0, w.threads, w.wallSeconds,
        w.cpuSeconds, (long long)w.rays, (long long)w.samples, (long long)w.probes,
        double(w.rays) / w.cpuSeconds * 1e-6, double(w.probes) / w.wallSeconds, e.meanIrradianceRel,
        e.medianIrradianceRel, e.maxIrradianceRel, e.rmsIrradianceRel, e.meanRadianceRel,
        e.rmsL0Rel, e.rmsIrradianceLumRel, e.meanStdError, e.rmsStdError, e.meanStdErrorL0,
        e.honesty, e.honestyL0, e.honestyIrradiance, e.meanSamples, e.refMeanIrradianceRel,
        e.refMeanStdError, w.stoppedByTarget, w.measuredWithinTarget, w.measuredWithin2Target,
        w.stoppedRmsOverTarget, e.meanSignedL0, e.meanSignedL0StdError, w.repeatsIdentical ? 1 : 0);
  }
  return csv;
}

std::string AdaptiveCsv(const BenchResults& r) {
  std::string csv =
      "scene,config,target_rel_error,batches,probe,samples,std_error,irr_lum_err,std_error_l0,"
      "l0_err,irr_err,irr_err_expected\n";
  for (const BakeRow& w : r.rows) {
    for (const ProbeErrors& e : w.probeErrors) {
      csv += Format("%s,%s,%g,%d,%lld,%.0f,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n", w.scene.c_str(),
                    w.config.c_str(), w.targetRelError, w.batches, (long long)e.probe, e.samples,
                    e.stdError, e.irradianceLumRel, e.stdErrorL0, e.l0Rel, e.irradianceRel,
                    e.irradiancePredicted);
    }
  }
  return csv;
}

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += Format("\\u%04x", c);
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string JsonNumber(double v) {
  return std::isfinite(v) ? Format("%.9g", v) : "null";
}

// Comma-separated JSON numbers.
std::string JoinNumbers(const std::vector<double>& values) {
  std::string out;
  for (size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + JsonNumber(values[i]);
  return out;
}

std::string Json(const BenchResults& r) {
  std::string j = "{\n";
  j += "  \"date\": " + JsonString(r.date) + ",\n  \"host\": " + JsonString(r.host) +
       ",\n  \"generator\": " + JsonString(r.generator) +
       Format(
           ",\n  \"quick\": %s,\n  \"hardwareThreads\": %d,\n  \"loadStart\": %s,\n  "
           "\"loadEnd\": %s,\n  \"totalSeconds\": %s,\n",
           r.quick ? "true" : "false", r.hardwareThreads, JsonNumber(r.loadStart).c_str(),
           JsonNumber(r.loadEnd).c_str(), JsonNumber(r.totalSeconds).c_str());
  j += "  \"presets\": " + JsonString(r.presetText) + ",\n  \"ladder\": [";
  for (size_t i = 0; i < r.ladder.size(); ++i)
    j += Format("%s%lld", i ? ", " : "", (long long)r.ladder[i]);
  j += "],\n  \"scenes\": [\n";
  for (size_t i = 0; i < r.scenes.size(); ++i) {
    const SceneInfo& s = r.scenes[i];
    j += Format(
        "    {\"name\": %s, \"description\": %s, \"triangles\": %lld, \"gridProbes\": "
        "%lld, \"bakedProbes\": %lld, \"reference\": %s, \"depthBiasIrradiance\": %s}%s\n",
        JsonString(s.name).c_str(), JsonString(s.description).c_str(), (long long)s.triangles,
        (long long)s.gridProbes, (long long)s.bakedProbes, JsonString(s.referenceText).c_str(),
        JsonNumber(s.depthBiasIrradiance).c_str(), i + 1 < r.scenes.size() ? "," : "");
  }
  j += "  ],\n  \"bakes\": [\n";
  for (size_t i = 0; i < r.rows.size(); ++i) {
    const BakeRow& w = r.rows[i];
    const ErrorSummary& e = w.error;
    j += Format(
        "    {\"scene\": %s, \"config\": %s, \"group\": %s, \"reference\": %s, "
        "\"samplesPerProbe\": %lld, \"targetRelError\": %s, \"shOrder\": %d, \"maxDepth\": %d, "
        "\"batches\": %d, \"estimator\": %s, \"sampler\": %s, \"russianRoulette\": %s, "
        "\"threads\": %d, \"wallSeconds\": %s, \"cpuSeconds\": %s, \"rays\": %lld, \"samples\": "
        "%lld, \"probes\": %lld, \"irradianceErrorMean\": %s, \"irradianceErrorMedian\": %s, "
        "\"irradianceErrorMax\": %s, \"radianceErrorMean\": %s, \"l0ErrorRms\": %s, "
        "\"irradianceLumErrorRms\": %s, \"stdErrorMean\": %s, \"stdErrorL0Mean\": %s, "
        "\"honesty\": %s, \"honestyL0\": %s, \"honestyIrradiance\": %s, \"meanSamples\": %s, "
        "\"stoppedByTarget\": %s, \"measuredWithinTarget\": %s, \"stoppedRmsOverTarget\": %s, "
        "\"meanSignedL0\": %s, \"meanSignedL0StdError\": %s, \"repeatsIdentical\": %s}%s\n",
        JsonString(w.scene).c_str(), JsonString(w.config).c_str(), JsonString(w.group).c_str(),
        JsonString(w.reference).c_str(), (long long)w.samplesPerProbe,
        JsonNumber(w.targetRelError).c_str(), w.shOrder, w.maxDepth, w.batches,
        JsonString(w.estimator).c_str(), JsonString(w.sampler).c_str(),
        w.russianRoulette ? "true" : "false", w.threads, JsonNumber(w.wallSeconds).c_str(),
        JsonNumber(w.cpuSeconds).c_str(), (long long)w.rays, (long long)w.samples,
        (long long)w.probes, JsonNumber(e.meanIrradianceRel).c_str(),
        JsonNumber(e.medianIrradianceRel).c_str(), JsonNumber(e.maxIrradianceRel).c_str(),
        JsonNumber(e.meanRadianceRel).c_str(), JsonNumber(e.rmsL0Rel).c_str(),
        JsonNumber(e.rmsIrradianceLumRel).c_str(), JsonNumber(e.meanStdError).c_str(),
        JsonNumber(e.meanStdErrorL0).c_str(), JsonNumber(e.honesty).c_str(),
        JsonNumber(e.honestyL0).c_str(), JsonNumber(e.honestyIrradiance).c_str(),
        JsonNumber(e.meanSamples).c_str(), JsonNumber(w.stoppedByTarget).c_str(),
        JsonNumber(w.measuredWithinTarget).c_str(), JsonNumber(w.stoppedRmsOverTarget).c_str(),
        JsonNumber(e.meanSignedL0).c_str(), JsonNumber(e.meanSignedL0StdError).c_str(),
        w.repeatsIdentical ? "true" : "false", i + 1 < r.rows.size() ? "," : "");
  }
  j += "  ],\n  \"throughput\": [\n";
  for (size_t i = 0; i < r.throughput.size(); ++i) {
    const ThroughputInfo& tp = r.throughput[i];
    j += Format(
        "    {\"scene\": %s, \"triangles\": %lld, \"tracerCpuMrays\": %s, "
        "\"tracerWallMrays\": %s, \"rays\": %lld, \"intersectRays\": %lld, "
        "\"shadowRays\": %lld, \"embreeShare\": %s, \"bakeCpuSeconds\": %s, "
        "\"setupCpuSeconds\": %s, \"setupRays\": %lld, \"pairedFractions\": [%s], "
        "\"pairedCpus\": [%s], \"raw\": [",
        JsonString(tp.scene).c_str(), (long long)tp.raw.triangles,
        JsonNumber(tp.tracerCpuMrays).c_str(), JsonNumber(tp.tracerWallMrays).c_str(),
        (long long)tp.rays, (long long)tp.intersectRays, (long long)tp.shadowRays,
        JsonNumber(tp.embreeOnlySeconds / tp.bakeCpuSeconds).c_str(),
        JsonNumber(tp.bakeCpuSeconds).c_str(), JsonNumber(tp.setupCpuSeconds).c_str(),
        (long long)tp.setupRays, JoinNumbers(tp.pairedFractions).c_str(),
        JoinNumbers(std::vector<double>(tp.pairedCpus.begin(), tp.pairedCpus.end())).c_str());
    for (size_t k = 0; k < tp.raw.rates.size(); ++k) {
      const RawRate& rr = tp.raw.rates[k];
      j += Format(
          "%s{\"rays\": %s, \"api\": %s, \"threads\": %d, \"wallMrays\": %s, "
          "\"cpuMrays\": %s}",
          k ? ", " : "", JsonString(rr.rays).c_str(), JsonString(rr.api).c_str(), rr.threads,
          JsonNumber(rr.wallMraysPerSecond).c_str(), JsonNumber(rr.cpuMraysPerSecond).c_str());
    }
    j += "]";
    if (const ReplayInfo& rp = tp.replay; rp.measured) {
      j += Format(", \"replay\": {\"stride\": %llu, \"calls\": %lld", (unsigned long long)rp.stride,
                  (long long)rp.calls);
      for (int k = 0; k < kRayKinds; ++k)
        j += Format(", \"%s\": {\"rays\": %lld, \"cast\": %lld}", RayKindName(RayKind(k)),
                    (long long)rp.rays[k], (long long)rp.cast[k]);
      j += Format(
          ", \"packed\": %lld, \"tracerMrays\": [%s], \"singleMrays\": [%s], \"packetMrays\": "
          "[%s], \"fractions\": [%s], \"cpus\": [%s], \"rates\": [",
          (long long)rp.packed, JoinNumbers(rp.tracerMrays).c_str(),
          JoinNumbers(rp.singleMrays).c_str(), JoinNumbers(rp.packetMrays).c_str(),
          JoinNumbers(rp.fractions).c_str(),
          JoinNumbers(std::vector<double>(rp.cpus.begin(), rp.cpus.end())).c_str());
      for (size_t k = 0; k < rp.rates.size(); ++k) {
        const ReplayRate& rr = rp.rates[k];
        j += Format("%s{\"rays\": %s, \"api\": %s, \"count\": %lld, \"cpuMrays\": %s}",
                    k ? ", " : "", JsonString(rr.rays).c_str(), JsonString(rr.api).c_str(),
                    (long long)rr.count, JsonNumber(rr.cpuMraysPerSecond).c_str());
      }
      j += "]}";
    }
    j += Format("}%s\n", i + 1 < r.throughput.size() ? "," : "");
  }
  j += "  ],\n";
  const ScalingInfo& sc = r.scaling;
  auto list = [](const std::vector<double>& v) {
    std::string s = "[";
    for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + JsonNumber(v[i]);
    return s + "]";
  };
  j += Format(
      "  \"scaling\": {\"scene\": %s, \"samplesPerProbe\": %lld, \"probes\": %lld, "
      "\"wall1\": %s, \"wall2\": %s, \"cpu1\": %s, \"cpu2\": %s, \"load\": %s, "
      "\"rawEmbreeRatio\": %s},\n",
      JsonString(sc.scene).c_str(), (long long)sc.samplesPerProbe, (long long)sc.probes,
      list(sc.wall1).c_str(), list(sc.wall2).c_str(), list(sc.cpu1).c_str(), list(sc.cpu2).c_str(),
      JsonNumber(sc.load).c_str(), JsonNumber(sc.rawRatio).c_str());
  const MemoryInfo& m = r.memory;
  j += Format(
      "  \"memory\": {\"measured\": %s, \"note\": %s, \"probes\": %lld, "
      "\"samplesPerProbe\": %lld, \"bakeSeconds\": %s, \"baselineRssBytes\": %lld, "
      "\"peakBakeBytes\": %lld, \"shBytes\": %lld, \"volumeBytes\": %lld, "
      "\"peakWriteExtraBytes\": %lld, \"vdbBytes\": %lld, \"writeSeconds\": %s}\n}\n",
      m.measured ? "true" : "false", JsonString(m.note).c_str(), (long long)m.probes,
      (long long)m.samplesPerProbe, JsonNumber(m.bakeSeconds).c_str(), (long long)m.baselineRss,
      (long long)m.peakBake, (long long)m.shBytes, (long long)m.volumeBytes,
      (long long)m.peakWriteExtra, (long long)m.vdbBytes, JsonNumber(m.writeSeconds).c_str());
  return j;
}

// ---- blocks embedded in the documents (kBenchDocuments) ----

// Scenes as the documents name them.
std::string SceneTitle(const std::string& scene) {
  if (scene == "sky_sphere") return "closed-form scene";
  if (scene == "demo") return "demo room";
  return scene;
}

std::string TimeToErrorBlock(const BenchResults& r) {
  const std::pair<const char*, const char*> configs[] = {
      {"naive", "naive: uniform directions, no NEE, independent numbers"},
      {"nee_sobol", "NEE only, Sobol"},
      {"nee_mis_independent", "NEE + MIS, independent numbers"},
      {"nee_mis_sobol", "**NEE + MIS, Sobol (the default)**"}};
  const double levels[] = {0.1, 0.05, 0.02};
  std::string md = "| demo room, CPU time to a mean error of |";
  for (double e : levels) md += Format(" %s |", Pct(e, 2).c_str());
  md += "\n| --- | --- | --- | --- |\n";
  for (const auto& [config, label] : configs) {
    const std::vector<Point> curve = Curve(r, "demo", config);
    if (curve.empty()) continue;
    const bool bold = std::string(config) == "nee_mis_sobol";
    md += Format("| %s |", label);
    for (double e : levels) {
      const std::string t = TimeText(TimeToError(curve, e));
      md += bold ? Format(" **%s** |", t.c_str()) : Format(" %s |", t.c_str());
    }
    md += "\n";
  }
  md += "\n(`~`: extrapolated past the largest sample count with error ∝ time^-1/2.)\n";
  return md;
}

std::string SpeedupsBlock(const BenchResults& r) {
  std::string parts;
  for (const SceneInfo& sc : r.scenes) {
    const std::vector<Point> naive = Curve(r, sc.name, "naive"),
                             best = Curve(r, sc.name, "nee_mis_sobol");
    std::string factors;
    for (double e : {0.1, 0.05}) {
      const TimeTo a = TimeToError(naive, e), b = TimeToError(best, e);
      if (a.how == Reach::kNone || b.how == Reach::kNone) continue;
      const double ratio = a.time / b.time;
      factors += Format(ratio >= 10 ? "%s%.0f×" : "%s%.2g×", factors.empty() ? "" : " and ", ratio);
    }
    if (factors.empty()) continue;
    parts += Format("%s%s on the %s", parts.empty() ? "" : ", ", factors.c_str(),
                    SceneTitle(sc.name).c_str());
  }
  std::string slopes;
  for (const SceneInfo& sc : r.scenes)
    slopes += Format("%s%.2f (%s)", slopes.empty() ? "" : ", ",
                     ErrorSlope(r, sc.name, "nee_mis_sobol"), SceneTitle(sc.name).c_str());
  return Format(
      "Against the naive estimator, NEE + MIS with Sobol reaches 10%% and 5%% error sooner by %s "
      "(extrapolated where the naive one never got there). Its error falls as samples to the "
      "power %s: -0.5 is plain Monte Carlo's rate.\n",
      parts.c_str(), slopes.c_str());
}

// A table cell: the time curve `a` takes to reach error e over the time `b` takes ("~" when
// either is extrapolated), or kNoRatio when either never gets there or starts below it.
constexpr const char* kNoRatio = " - |";
std::string RatioCell(const std::vector<Point>& a, const std::vector<Point>& b, double e) {
  const TimeTo ta = TimeToError(a, e), tb = TimeToError(b, e);
  if (ta.how == Reach::kNone || tb.how == Reach::kNone || ta.how == Reach::kBelowAtFirst ||
      tb.how == Reach::kBelowAtFirst)
    return kNoRatio;
  return Format(" %s%.2f× |",
                ta.how == Reach::kExtrapolated || tb.how == Reach::kExtrapolated ? "~" : "",
                ta.time / tb.time);
}

// Time to a mean error of 5%, 2% and 1% with the default and with the default of baker version 19
// (before light traced from directional lights, the environment guide and the visibility floor
// of 1/32), on each scene.
std::string FormerDefaultBlock(const BenchResults& r) {
  const double levels[] = {0.05, 0.02, 0.01};
  std::string md;
  for (const SceneInfo& sc : r.scenes) {
    const std::vector<Point> with = Curve(r, sc.name, "nee_mis_sobol"),
                             without = Curve(r, sc.name, "nee_mis_sobol_v19");
    if (with.empty() || without.empty()) continue;
    md += "| " + SceneTitle(sc.name) + ", CPU time to a mean error of |";
    for (double e : levels) md += Format(" %s |", Pct(e, 2).c_str());
    md += "\n| --- |";
    for (size_t i = 0; i < std::size(levels); ++i) md += " --- |";
    md += "\n| the default of baker version 19 |";
    for (double e : levels) md += Format(" %s |", TimeText(TimeToError(without, e)).c_str());
    md += "\n| **the default now** |";
    for (double e : levels) md += Format(" **%s** |", TimeText(TimeToError(with, e)).c_str());
    md += "\n| time before / time now |";
    for (double e : levels) md += RatioCell(without, with, e);
    md += "\n\n";
  }
  if (md.empty()) return "Not measured.\n";
  return md.find('~') == std::string::npos ? md : md + "(`~`: extrapolated as above.)\n";
}

// Time to equal error with 16 batches (the default before baker version 16) against the default
// of 4, per scene: what the larger point set per batch buys.
std::string BatchesBlock(const BenchResults& r) {
  const double levels[] = {0.05, 0.02, 0.01};
  std::string md = "| CPU time to a mean error of, 16 batches against the default 4 |";
  for (double e : levels) md += Format(" %s |", Pct(e, 2).c_str());
  md += "\n| --- |";
  for (size_t i = 0; i < std::size(levels); ++i) md += " --- |";
  md += "\n";
  bool any = false;
  for (const SceneInfo& sc : r.scenes) {
    const std::vector<Point> four = Curve(r, sc.name, "nee_mis_sobol"),
                             sixteen = Curve(r, sc.name, "nee_mis_sobol_b16");
    if (four.empty() || sixteen.empty()) continue;
    md += "| " + SceneTitle(sc.name) + " |";
    for (double e : levels) {
      const std::string cell = RatioCell(sixteen, four, e);
      any = any || cell != kNoRatio;
      md += cell;
    }
    md += "\n";
  }
  return any ? md : "Not measured.\n";
}

std::string PresetsBlock(const BenchResults& r) {
  std::string md = "| preset | samples (cap) / depth / target |";
  for (const SceneInfo& sc : r.scenes)
    md += Format(" %s: error, CPU ms per probe |", SceneTitle(sc.name).c_str());
  md += "\n| --- | --- |";
  for (size_t i = 0; i < r.scenes.size(); ++i) md += " --- |";
  md += "\n";
  for (const char* preset : {"PREVIEW", "PRODUCTION", "REFERENCE"}) {
    const BakeRow* any = nullptr;
    std::string cells;
    for (const SceneInfo& sc : r.scenes) {
      const BakeRow* row = FindRow(r, sc.name, std::string("preset_") + preset);
      if (!any) any = row;
      cells += row ? Format(" %s, %.2g |", Pct(row->error.meanIrradianceRel, 2).c_str(),
                            1e3 * row->cpuSeconds / double(std::max<int64_t>(row->probes, 1)))
                   : " - |";
    }
    if (!any) continue;
    md += Format(
        "| `%s` | %lld / %d / %s |%s\n", preset, (long long)any->samplesPerProbe, any->maxDepth,
        any->targetRelError > 0 ? Pct(any->targetRelError, 2).c_str() : "none", cells.c_str());
  }
  md +=
      "\nErrors are against depth-64 references, so they include each preset's depth "
      "truncation.\n";
  return md;
}

std::string AdaptiveBlock(const BenchResults& r) {
  std::string md = Format(
      "| scene | target | mean samples per probe (cap %lld) | RMS measured error / target |\n"
      "| --- | --- | --- | --- |\n",
      r.ladder.empty() ? 0LL : (long long)r.ladder.back());
  for (const BakeRow& row : r.rows) {
    if (row.group != "adaptive" || row.batches != 64) continue;
    md += Format("| %s | %s | %.0f | %.2f |\n", SceneTitle(row.scene).c_str(),
                 Pct(row.targetRelError, 2).c_str(), row.error.meanSamples,
                 row.error.rmsIrradianceLumRel / row.targetRelError);
  }
  return md;
}

std::string HonestyBlock(const BenchResults& r) {
  // Per scene: the spread over every ladder bake but the naive estimator's.
  std::string md =
      "| scene | measured / reported irradiance error (`std_error`): median (min to max) | the "
      "same for L0 (`std_error_l0`) |\n| --- | --- | --- |\n";
  std::vector<double> all;
  for (const SceneInfo& s : r.scenes) {
    std::vector<double> h, l0;
    for (const BakeRow& row : r.rows)
      if (row.scene == s.name && row.group == "ladder" && row.config != "naive") {
        h.push_back(row.error.honesty);
        l0.push_back(row.error.honestyL0);
      }
    if (h.empty()) continue;
    all.insert(all.end(), h.begin(), h.end());
    md += Format("| %s | %.2f (%.2f to %.2f) | %.2f (%.2f to %.2f) |\n", SceneTitle(s.name).c_str(),
                 Median(h), *std::min_element(h.begin(), h.end()),
                 *std::max_element(h.begin(), h.end()), Median(l0),
                 *std::min_element(l0.begin(), l0.end()), *std::max_element(l0.begin(), l0.end()));
  }
  if (all.empty()) return "Not measured.\n";
  md += Format(
      "\nOver every bake of the sample-count ladders but the naive estimator's (%zu bakes): "
      "median %.2f, from %.2f to %.2f.\n",
      all.size(), Median(all), *std::min_element(all.begin(), all.end()),
      *std::max_element(all.begin(), all.end()));
  return md;
}

}  // namespace

std::string ReplayMarkdown(const BenchResults& r) {
  bool any = false;
  for (const ThroughputInfo& tp : r.throughput) any = any || tp.replay.measured;
  if (!any) return "";
  std::string md =
      "\n## Throughput against Embree on the tracer's own rays\n\nA section of the default "
      "bake (1 thread; the probes whose key falls in 1 of `stride`, every batch) recorded ray by "
      "ray as the tracer casts it (probe, bounce and shadow rays, in cast order), then replayed "
      "through raw Embree on the same scene: one by one (rtcIntersect1 / rtcOccluded1, \"single\") "
      "and in 8-wide packets of consecutive rays of one kind (rtcIntersect8 / rtcOccluded8, "
      "\"packet8\"). \"Fraction\": the tracer's cast rays per CPU second in the same section "
      "(measured in a bake that records nothing) over the better replay's; pairs of the two on one "
      "CPU, median (range). 1 would be a tracer that costs nothing but its Embree calls; the rest "
      "is shading, sampling and bookkeeping. \"Probe-ray fraction\": the earlier figure, the "
      "whole bake against rtcIntersect1 on coherent rays from the probes (pairs, median).\n\n"
      "| scene | section: stride, calls | rays probe / bounce / shadow (not cast) | cast in "
      "packets | tracer Mrays/CPU-s | replay single | replay packet8 | fraction of the best replay "
      "| probe-ray fraction |\n|---|---|---|---|---|---|---|---|---|\n";
  for (const ThroughputInfo& tp : r.throughput) {
    const ReplayInfo& rp = tp.replay;
    if (!rp.measured) continue;
    const int64_t notCast =
        (rp.rays[0] - rp.cast[0]) + (rp.rays[1] - rp.cast[1]) + (rp.rays[2] - rp.cast[2]);
    std::vector<double> pf = tp.pairedFractions;
    md += Format(
        "| %s | 1/%llu, %lld | %lld / %lld / %lld (%lld) | %.2f | %.3g | %.3g | %.3g | %s | %s |\n",
        tp.scene.c_str(), (unsigned long long)rp.stride, (long long)rp.calls, (long long)rp.rays[0],
        (long long)rp.rays[1], (long long)rp.rays[2], (long long)notCast,
        double(rp.packed) / double(std::max<int64_t>(rp.CastRays(), 1)), Median(rp.tracerMrays),
        Median(rp.singleMrays), Median(rp.packetMrays), PairedText(rp.fractions).c_str(),
        pf.empty() ? "-" : Format("%.2f", Median(pf)).c_str());
  }
  md +=
      "\nReplay rates by kind, Mrays per CPU second (each kind's rays alone, in cast order):\n\n"
      "| scene | rays | single | packet8 |\n|---|---|---|---|\n";
  for (const ThroughputInfo& tp : r.throughput) {
    for (const ReplayRate& one : tp.replay.rates) {
      if (one.api != "single") continue;
      const ReplayRate* packet = nullptr;
      for (const ReplayRate& p : tp.replay.rates)
        if (p.api == "packet8" && p.rays == one.rays) packet = &p;
      md += Format("| %s | %s (%lld) | %.3g | %s |\n", tp.scene.c_str(), one.rays.c_str(),
                   (long long)one.count, one.cpuMraysPerSecond,
                   packet ? Format("%.3g", packet->cpuMraysPerSecond).c_str() : "-");
    }
  }
  md += "\nPairs in run order (tracer / single / packet8 Mrays per CPU-s, fraction, CPU):\n\n";
  for (const ThroughputInfo& tp : r.throughput) {
    const ReplayInfo& rp = tp.replay;
    if (!rp.measured) continue;
    md += "- " + tp.scene + ":";
    for (size_t k = 0; k < rp.fractions.size(); ++k)
      md += Format(" %.3g / %.3g / %.3g, %.2f (CPU %d);", rp.tracerMrays[k], rp.singleMrays[k],
                   rp.packetMrays[k], rp.fractions[k], k < rp.cpus.size() ? rp.cpus[k] : -1);
    md += "\n";
  }
  return md;
}

namespace {

std::string ThroughputBlock(const BenchResults& r) {
  std::string head = "| throughput, one thread |", rule = "| --- |", mrays, fraction, paired,
              replay;
  bool anyReplay = false;
  for (const ThroughputInfo& tp : r.throughput) {
    const RawRate* raw = tp.raw.Find("probe random", "rtcIntersect1", 1);
    if (!raw) continue;
    std::vector<double> rf = tp.replay.fractions;
    std::sort(rf.begin(), rf.end());
    anyReplay = anyReplay || !rf.empty();
    replay +=
        rf.empty() ? " - |" : Format(" %.2f (%.2f–%.2f) |", Median(rf), rf.front(), rf.back());
    head += Format(" %s |", SceneTitle(tp.scene).c_str());
    rule += " --- |";
    mrays += Format(" %.3g |", tp.tracerCpuMrays);
    fraction += Format(" %.2f |", tp.tracerCpuMrays / raw->cpuMraysPerSecond);
    std::vector<double> f = tp.pairedFractions;
    std::sort(f.begin(), f.end());
    paired += f.empty() ? " - |" : Format(" %.2f (%.2f–%.2f) |", Median(f), f.front(), f.back());
  }
  return head + "\n" + rule +
         "\n| tracer Mrays per CPU-second (every ray, shadow rays included) |" + mrays +
         "\n| as a fraction of raw Embree (`rtcIntersect1`, the same probes' rays) |" + fraction +
         "\n| the same in back-to-back pairs on one CPU: median (range) |" + paired +
         (anyReplay
              ? "\n| as a fraction of raw Embree replaying the bake's own rays (the better of "
                "one by one and 8-wide packets), pairs: median (range) |" +
                    replay
              : std::string()) +
         "\n";
}

std::string ScalingMemoryBlock(const BenchResults& r) {
  std::string md;
  const ScalingInfo& sc = r.scaling;
  if (const std::optional<ScalingBest> best = BestOf(sc)) {
    const auto [w1, w2, c1, c2] = *best;
    md += Format(
        "- Two threads bake the %s %.2f× as fast as one (bit-identical results); raw Embree's "
        "own loop reached %.2f× at the same time, and the bake kept %.2f× as many CPUs busy.\n",
        SceneTitle(sc.scene).c_str(), w1 / w2, sc.rawRatio, (w1 / w2) * (c2 / c1));
  }
  const MemoryInfo& m = r.memory;
  if (m.measured && m.shBytes > 0)
    md += Format(
        "- A dense %lld-probe order-2 bake with irradiance peaks at %.2f× the size of its SH data "
        "(%.0f MiB); its .vdb is %.0f MiB.\n",
        (long long)m.probes, double(m.peakBake) / double(m.shBytes), m.peakBake / kMiB,
        m.vdbBytes / kMiB);
  return md.empty() ? "Not measured.\n" : md;
}

// Light a depth limit leaves out: the mean signed L0 difference against the deep reference at every
// depth the bench tried, for the scenes where some depth leaves out more than 3 standard errors.
std::string DepthBlock(const BenchResults& r) {
  std::vector<std::string> scenes;
  std::vector<int> depths;
  for (const SceneInfo& sc : r.scenes) {
    bool resolved = false;
    for (const BakeRow& row : r.rows) {
      if (row.scene != sc.name || row.group != "depth") continue;
      resolved = resolved || std::abs(row.error.meanSignedL0) > 3 * row.error.meanSignedL0StdError;
      if (std::find(depths.begin(), depths.end(), row.maxDepth) == depths.end())
        depths.push_back(row.maxDepth);
    }
    if (resolved) scenes.push_back(sc.name);
  }
  if (scenes.empty()) return "Not measured.\n";
  std::sort(depths.begin(), depths.end());
  std::string md = "| maxDepth |";
  for (const std::string& scene : scenes) md += Format(" %s |", SceneTitle(scene).c_str());
  md += "\n| --- |";
  for (size_t i = 0; i < scenes.size(); ++i) md += " --- |";
  md += "\n";
  for (int depth : depths) {
    md += Format("| %d |", depth);
    for (const std::string& scene : scenes) {
      const BakeRow* found = nullptr;
      for (const BakeRow& row : r.rows)
        if (row.scene == scene && row.group == "depth" && row.maxDepth == depth) found = &row;
      md += found ? Format(" %+.2g%% ± %.2g%% |", 100 * found->error.meanSignedL0,
                           100 * found->error.meanSignedL0StdError)
                  : " - |";
    }
    md += "\n";
  }
  return md;
}

// Other settings against the default, as CPU time to a 5% error on the demo room.
std::string SettingsBlock(const BenchResults& r) {
  const TimeTo base = TimeToError(Curve(r, "demo", "nee_mis_sobol"), 0.05);
  if (base.how == Reach::kNone) return "Not measured.\n";
  std::string md = "| demo room, CPU time to a 5% error, against the default |  |\n| --- | --- |\n";
  const std::pair<const char*, const char*> configs[] = {
      {"order1", "SH order 1 (against its own truncation)"},
      {"order3", "SH order 3"},
      {"nee_mis_sobol_no_rr", "Russian roulette off"},
      {"nee_mis_independent", "independent numbers instead of Sobol"}};
  for (const auto& [config, label] : configs) {
    const TimeTo t = TimeToError(Curve(r, "demo", config), 0.05);
    if (t.how == Reach::kNone) continue;
    md += Format("| %s | %s%.2f× |\n", label,
                 t.how == Reach::kExtrapolated || base.how == Reach::kExtrapolated ? "~" : "",
                 t.time / base.time);
  }
  return md;
}

std::map<std::string, std::string> DocBlocks(const BenchResults& r, const std::string& root) {
  std::map<std::string, std::string> blocks;
  blocks["run"] = Format(
      "Figures of the last bench run (`scripts/bench.sh`%s: %s, %s; host with %d hardware "
      "threads, load average %.2f at the start). Times are CPU seconds on one core; an error is "
      "the mean over probes of the relative L2 error of the reconstructed irradiance over the "
      "sphere of normals, against a reference. Every figure and the plots: "
      "[tests/bench/results/results.md](%stests/bench/results/results.md).\n",
      r.quick ? " --quick" : "", r.date.c_str(), r.generator.c_str(), r.hardwareThreads,
      r.loadStart, root.c_str());
  blocks["time-to-error"] = TimeToErrorBlock(r);
  blocks["speedups"] = SpeedupsBlock(r);
  blocks["presets"] = PresetsBlock(r);
  blocks["adaptive"] = AdaptiveBlock(r);
  blocks["honesty"] = HonestyBlock(r);
  blocks["throughput"] = ThroughputBlock(r);
  blocks["scaling-memory"] = ScalingMemoryBlock(r);
  blocks["depth"] = DepthBlock(r);
  blocks["settings"] = SettingsBlock(r);
  blocks["batches"] = BatchesBlock(r);
  blocks["former-default"] = FormerDefaultBlock(r);
  return blocks;
}

// `text` with the content of every "<!-- bench:NAME -->" ... "<!-- /bench:NAME -->" pair replaced
// by blocks[NAME]; `document` names the file in errors.
absl::StatusOr<std::string> SpliceBlocks(const std::string& text,
                                         const std::map<std::string, std::string>& blocks,
                                         const std::string& document) {
  static constexpr std::string_view kOpen = "<!-- bench:", kClose = " -->";
  std::string out;
  size_t at = 0;
  while (true) {
    const size_t open = text.find(kOpen, at);
    if (open == std::string::npos) break;
    const size_t nameEnd = text.find(kClose, open + kOpen.size());
    if (nameEnd == std::string::npos)
      return absl::InvalidArgumentError(document + ": unterminated bench marker");
    const std::string name = text.substr(open + kOpen.size(), nameEnd - open - kOpen.size());
    const auto block = blocks.find(name);
    if (block == blocks.end())
      return absl::InvalidArgumentError(document + ": unknown bench block \"" + name + "\"");
    const std::string end = "<!-- /bench:" + name + " -->";
    const size_t startLine = text.find('\n', nameEnd);
    const size_t close = text.find(end, nameEnd);
    if (startLine == std::string::npos || close == std::string::npos || close < startLine)
      return absl::InvalidArgumentError(document + ": bench block \"" + name + "\" has no " + end);
    out += text.substr(at, startLine + 1 - at);
    out += block->second;
    at = close;
  }
  return out + text.substr(at);
}

}  // namespace

absl::Status UpdateDocuments(const BenchResults& results, const std::string& sourceDir) {
  for (const std::string document : kBenchDocuments) {
    const std::string path = sourceDir + "/" + document;
    PB_ASSIGN_OR_RETURN(const std::string text, ReadFileBytes(path));
    // Links in the blocks are relative to the document's folder.
    const std::string root = document.find('/') == std::string::npos ? "" : "../";
    PB_ASSIGN_OR_RETURN(const std::string updated,
                        SpliceBlocks(text, DocBlocks(results, root), document));
    if (updated != text) PB_RETURN_IF_ERROR(WriteFileAtomic(path, updated));
  }
  return absl::OkStatus();
}

absl::Status WriteReports(const BenchResults& results, const std::string& dir) {
  std::filesystem::create_directories(dir);
  PB_RETURN_IF_ERROR(WriteFileAtomic(dir + "/results.md", Markdown(results)));
  PB_RETURN_IF_ERROR(WriteFileAtomic(dir + "/results.csv", Csv(results)));
  PB_RETURN_IF_ERROR(WriteFileAtomic(dir + "/results.json", Json(results)));
  PB_RETURN_IF_ERROR(WriteFileAtomic(dir + "/adaptive_probes.csv", AdaptiveCsv(results)));
  for (const SceneInfo& s : results.scenes) {
    const std::string svg =
        Plot(results, s.name, "probebake: error vs time, " + s.name + " scene", s.description);
    if (!svg.empty())
      PB_RETURN_IF_ERROR(WriteFileAtomic(dir + "/error_vs_time_" + s.name + ".svg", svg));
  }
  return absl::OkStatus();
}

}  // namespace probebake::bench
