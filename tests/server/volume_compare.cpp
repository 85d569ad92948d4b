#include "volume_compare.h"

#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "probebake/volume/vdb_io.h"

namespace probebake::testing {

void ExpectSameVolume(const std::filesystem::path& a, const std::filesystem::path& b) {
  auto va = ReadProbeVolume(a.string());
  auto vb = ReadProbeVolume(b.string());
  ASSERT_TRUE(va.ok()) << va.status();
  ASSERT_TRUE(vb.ok()) << vb.status();
  const ProbeVolume &x = va->volume, &y = vb->volume;
  EXPECT_EQ(x.grid.ProbeCount(), y.grid.ProbeCount());
  EXPECT_EQ(x.grid.origin, y.grid.origin);
  EXPECT_EQ(x.grid.spacing, y.grid.spacing);
  EXPECT_EQ(x.shOrder, y.shOrder);
  EXPECT_EQ(x.active, y.active);
  auto same = [](const std::vector<float>& p, const std::vector<float>& q,
                 const std::string& what) {
    ASSERT_EQ(p.size(), q.size()) << what;
    for (size_t i = 0; i < p.size(); ++i)
      ASSERT_EQ(std::memcmp(&p[i], &q[i], sizeof(float)), 0)
          << what << "[" << i << "]: " << p[i] << " vs " << q[i];
  };
  ASSERT_EQ(x.radiance.size(), y.radiance.size());
  ASSERT_GT(x.radiance.size(), 0u);
  for (size_t c = 0; c < x.radiance.size(); ++c)
    same(x.radiance[c], y.radiance[c], "radiance " + std::to_string(c));
  ASSERT_EQ(x.irradiance.size(), y.irradiance.size());
  for (size_t c = 0; c < x.irradiance.size(); ++c)
    same(x.irradiance[c], y.irradiance[c], "irradiance " + std::to_string(c));
  same(x.validity, y.validity, "validity");
  same(x.stdError, y.stdError, "stdError");
  same(x.stdErrorL0, y.stdErrorL0, "stdErrorL0");
  same(x.sampleCount, y.sampleCount, "sampleCount");
  for (const auto& [key, value] : va->rawMetadata) {
    if (key == "stats") continue;
    EXPECT_EQ(vb->rawMetadata[key], value) << "metadata " << key;
  }
}

}  // namespace probebake::testing
