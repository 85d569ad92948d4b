#include "engine_test_util.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>

#include "google/protobuf/util/json_util.h"
#include "probebake/sh/sh_basis.h"
#include "probebake/sh/sh_convolution.h"
#include "volume/test_volumes.h"

namespace probebake::testing {

ProbeVolume PlausibleVolume(uint64_t seed) {
  TestVolumeSpec spec;
  spec.awkwardValues = false;
  spec.seed = seed;
  ProbeVolume volume = MakeTestVolume(spec);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  const int64_t n = volume.grid.ProbeCount();
  for (int64_t p = 0; p < n; ++p) {
    if (!volume.active[p]) continue;
    const Vec3d ambient{0.5 + u(rng), 0.5 + u(rng), 0.5 + u(rng)};
    const Vec3d power{2 * u(rng), 2 * u(rng), 2 * u(rng)};
    const double z = 2 * u(rng) - 1, phi = 2 * std::numbers::pi * u(rng);
    const double r = std::sqrt(std::max(0.0, 1 - z * z));
    double lobe[9];
    HenyeyGreensteinLobe(2, 0.6, {r * std::cos(phi), r * std::sin(phi), z}, lobe);
    for (int c = 0; c < volume.CoeffCount(); ++c)
      for (int ch = 0; ch < 3; ++ch) {
        double v = power[ch] * (c < 9 ? lobe[c] : 0);
        if (c == 0) v += ambient[ch] * std::sqrt(4 * std::numbers::pi);
        volume.radiance[c][3 * p + ch] = static_cast<float>(v);
      }
  }
  return volume;
}

int RunCommand(const std::string& command, std::string* out) {
  FILE* pipe = ::popen(command.c_str(), "r");
  if (!pipe) return -1;
  std::string text;
  char buffer[65536];
  size_t got;
  while ((got = std::fread(buffer, 1, sizeof buffer, pipe)) > 0) text.append(buffer, got);
  const int status = ::pclose(pipe);
  if (out) *out = std::move(text);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

bool HaveProgram(const std::string& program) {
  return RunCommand("command -v " + program + " >/dev/null 2>&1") == 0;
}

std::string ReadFileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << "cannot read " << path;
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

google::protobuf::Struct ParseJson(const std::string& text) {
  google::protobuf::Struct message;
  const auto status = google::protobuf::util::JsonStringToMessage(text, &message);
  EXPECT_TRUE(status.ok()) << status.message() << "\nin: " << text.substr(0, 400);
  return message;
}

Vec3d ToVec3(const google::protobuf::Value& value) {
  EXPECT_EQ(value.list_value().values_size(), 3) << value.DebugString();
  if (value.list_value().values_size() != 3) return {};
  const auto& v = value.list_value().values();
  return {v[0].number_value(), v[1].number_value(), v[2].number_value()};
}

}  // namespace probebake::testing
