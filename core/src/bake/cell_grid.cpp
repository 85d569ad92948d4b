#include "cell_grid.h"

#include <algorithm>
#include <cmath>

namespace probebake {
namespace {

constexpr int kMaxCellsPerAxis = 32;

}  // namespace

CellGrid CellGrid::Over(const Vec3d& loIn, const Vec3d& hiIn, int64_t maxCells) {
  CellGrid g;
  double longest = 0;
  for (int a = 0; a < 3; ++a) {
    if (!(hiIn[a] >= loIn[a])) return g;  // empty
    longest = std::max(longest, hiIn[a] - loIn[a]);
  }
  if (!(longest > 0) || !std::isfinite(longest)) return g;

  int perAxis = kMaxCellsPerAxis;
  for (;; perAxis = std::max(1, perAxis / 2)) {
    const double size = longest / perAxis;
    int64_t cells = 1;
    for (int a = 0; a < 3; ++a)
      cells *= std::max<int64_t>(1, int64_t(std::ceil((hiIn[a] - loIn[a]) / size)));
    if (cells <= maxCells || perAxis == 1) break;
  }
  const double size = longest / perAxis;
  const double margin = longest * 0x1p-20;
  for (int a = 0; a < 3; ++a) {
    const double extent = hiIn[a] - loIn[a];
    g.dims[a] = std::max(1, int(std::ceil(extent / size)));
    const double pad = std::max(margin, (g.dims[a] * size - extent) / 2);
    g.lo[a] = loIn[a] - pad;
    g.inverseSize[a] = g.dims[a] / (hiIn[a] + pad - g.lo[a]);
  }
  return g;
}

}  // namespace probebake
