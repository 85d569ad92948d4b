// A grid of cubic cells over a box: the regions of a scene that per-region tables hold their
// values for (light_visibility.h, environment_guide.h).
#pragma once

#include <cstdint>

#include "probebake/math/vec3.h"

namespace probebake {

struct CellGrid {
  // The finest grid over [lo, hi] (local coordinates) with at most maxCells cells: the longest
  // axis cut into 32, 16, ... 1 cubes, the other axes into as many as cover them (a flat axis, a
  // single floor, gets one layer a cell thick, centred on it). The box is padded by at least
  // 2^-20 of its size on every side: bounce vertices lie on the walls and floors that make its
  // faces, and points rounded a few ulps outside would fall out of it. Empty (dims 0) for an
  // empty, flat-in-every-axis or infinite box.
  static CellGrid Over(const Vec3d& lo, const Vec3d& hi, int64_t maxCells);

  bool Empty() const { return dims[0] == 0; }
  int64_t Count() const { return int64_t(dims[0]) * dims[1] * dims[2]; }

  // The cell holding p, (iz * ny + iy) * nx + ix, or -1 outside the padded box (a point on its
  // far face is in the last cell).
  int64_t CellOf(const Vec3d& p) const {
    int64_t cell = 0;
    for (int a = 2; a >= 0; --a) {
      const double x = (p[a] - lo[a]) * inverseSize[a];
      if (!(x >= 0 && x <= dims[a])) return -1;
      cell = cell * dims[a] + (x == dims[a] ? dims[a] - 1 : int64_t(x));
    }
    return cell;
  }

  // The point of cell `cell` at fractions f of its size along each axis.
  Vec3d Point(int64_t cell, const Vec3d& f) const {
    const int64_t ix = cell % dims[0];
    const int64_t iy = cell / dims[0] % dims[1];
    const int64_t iz = cell / (int64_t(dims[0]) * dims[1]);
    return {lo.x + (double(ix) + f.x) / inverseSize.x, lo.y + (double(iy) + f.y) / inverseSize.y,
            lo.z + (double(iz) + f.z) / inverseSize.z};
  }

  Vec3d lo, inverseSize;  // cells per unit length along each axis
  int dims[3] = {0, 0, 0};
};

}  // namespace probebake
