// Probe validity and relocation (docs/volume-format.md, `validity` and `offset`).
//
// Validity: a probe is invalid (inside geometry) when more than backfaceFraction of kValidityRays
// rays from it, one Sobol stream keyed by the probe's site, first hit a mesh's back face.
//
// Relocation (BakeSettings::relocationMaxOffset = f > 0), in the manner of Unity's virtual offset
// and DDGI's probe relocation: with R = f times the grid's smallest spacing and a clearance
// c = R / 4, a probe that is invalid, or has a mesh closer than c, is moved to the first free
// candidate of a fixed search: radii R k / 8 (k = 1..8, nearest first), and at each the 26
// lattice directions (6 faces, 12 edges, 8 corners of a cube, normalised, in that order). A
// candidate is free when
//   - no mesh lies within c of it (so it never sits on or against a surface);
//   - the straight move from the probe to it crosses no surface, except, for an invalid probe,
//     one back face (leaving the solid it is in): a move never passes through a wall, however
//     thin, into the room beyond, nor into another solid;
//   - it is valid by the test above, with its own rays.
// The search is a function of the grid point's world position and the scene alone, as the
// probe's site is (probe_site.h), so sub-grids relocate as the whole grid does. The offset is
// rounded to floats before use (the file stores it so), and the moved probe is exactly a probe
// placed at grid point + offset: its site, stream key and trace origin are that point's. A probe
// with no free candidate stays where it is (an invalid one stays invalid).
#pragma once

#include <cstdint>

#include "probe_site.h"
#include "probebake/math/vec3.h"
#include "probebake/scene/scene.h"
#include "tracer_scene.h"

namespace probebake {

// Rays per probe for the inside-geometry test. 128 directions of one Sobol stream resolve the
// fraction to 1/128, far finer than any sensible threshold.
inline constexpr int kValidityRays = 128;

// Whether the probe traced from local `origin` with stream key `key` is valid. Adds the rays
// traced to *rays.
bool ProbeValid(const TracerScene& tracer, const BakeSettings& settings, const Vec3d& origin,
                uint64_t key, int64_t* rays);

// Where a probe at world position `position` is traced from: its site, moved off a surface it
// lies on (TraceOrigin).
struct ProbeStart {
  Vec3d p;       // local
  uint64_t key;  // ProbeSite::key
  int moves;     // how often it was moved off a surface
};
ProbeStart StartAt(const ProbeSites& sites, const TracerScene& tracer, const Vec3d& position);

class ProbeRelocator {
 public:
  ProbeRelocator(const TracerScene& tracer, const ProbeSites& sites, const BakeSettings& settings,
                 const ProbeGrid& grid);
  bool Enabled() const { return maxOffset_ > 0; }
  // Whether the probe started at `start` (valid or not) should move: invalid, or a mesh within
  // the clearance.
  bool WantsMove(const ProbeStart& start, bool valid) const;
  // The search above for the probe at world `position` started at `start`: true and *offset when
  // a free candidate was found. Adds the rays traced to *rays.
  bool Find(const Vec3d& position, const ProbeStart& start, bool valid, Vec3f* offset,
            int64_t* rays) const;

 private:
  // Whether the straight move from `from` to `to` (local) crosses no surface but, when
  // `leaving`, one back face. Adds the rays traced to *rays.
  bool MoveIsClear(const Vec3d& from, const Vec3d& to, bool leaving, int64_t* rays) const;

  const TracerScene& tracer_;
  const ProbeSites& sites_;
  const BakeSettings& settings_;
  double maxOffset_ = 0;  // R, scene units
  double clearance_ = 0;  // c
};

}  // namespace probebake
