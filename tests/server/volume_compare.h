// Comparing two probe volume files bit for bit, as the end-to-end tests judge "the same bake".
#pragma once

#include <filesystem>

namespace probebake::testing {

// Every grid value, the grid and the metadata except `stats` (wall time, threads and the counts
// of the attempt that finished, which differ between a local, a server and a sharded bake) must
// agree bit for bit (gtest failures otherwise).
void ExpectSameVolume(const std::filesystem::path& a, const std::filesystem::path& b);

}  // namespace probebake::testing
