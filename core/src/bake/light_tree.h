// A bounding hierarchy over many finite lights, so that choosing one in proportion to an
// importance estimate at a shading point costs O(log n) instead of O(n) (LightSet keeps the exact
// linear choice for scenes with few lights).
//
// Each item is a light's bounding box and its weight W, the numerator of LightSet's importance:
// importance ~ W / d^2 (W = luminance x area for area lights, luminance x intensity for point
// lights). A cluster of n lights is estimated as a whole: W_sum times the mean of 1 / d^2 at the
// nearest and at the farthest point of its box from p, d^2 floored at the lights' spacing
// (r / n^(1/3), r half the box's diagonal; distance to the centre alone made the lights nearest p
// the least likely), and 0 when the whole box lies on or below the tangent plane of the shading
// point (normal n). A single light is estimated by the caller's exact importance (`leaf(light)`).
//
// Orientation (as in pbrt-v4's light BVH, after Conty Estevez and Kulla 2018): each light emits
// within theta_e of some normal in a cone (axis w, half-angle theta_o): theta_o = 0 and theta_e =
// 90 degrees for a one-sided area light, theta_e = the outer angle for a spot light, theta_o = 180
// degrees for lights emitting every way. A cluster bounds its lights' cones; it is estimated as 0
// where no direction from its bounding sphere to p is within theta_o + theta_e of w (a margin of
// 1e-9 in the cosine keeps the test conservative against rounding), and is scaled by the cosine
// of the smallest possible angle otherwise.
//
// Sample walks from the root choosing a child with probability proportional to the two children's
// estimates; Pmf recomputes the product of those probabilities for a given light, with the same
// arithmetic in the same order, so the two agree bit for bit (what MIS needs). The tree is exact
// in what it can reach: a light whose own importance is positive has positive probability, since
// every box containing it then reaches above the plane (the box test is monotone: a box with its
// support corner on or below the plane holds only points whose computed distance to it is also
// <= 0) and every cone containing its own lets it face p. Immutable after construction; const
// methods may be called from any thread.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "probebake/math/vec3.h"
#include "probebake/sampling/warps.h"

namespace probebake {

class LightTree {
 public:
  struct Item {
    Vec3d lo, hi;       // bounds of the light (local coordinates); a point has lo == hi
    double weight = 0;  // W >= 0
    double clamp = 0;   // the light's own floor on d^2 (> 0; LightSet: its area, 1e-300 for points)
    // Emission directions: within thetaE of a normal within thetaO of axis (radians; thetaO >= pi
    // means every direction).
    Vec3d axis{0, 0, 1};
    double thetaO = 3.14159265358979323846, thetaE = 1.5707963267948966;
    uint32_t light = 0;
  };

  // Precondition: items.size() >= 1 and < 2^32.
  explicit LightTree(std::vector<Item> items);

  size_t Size() const { return leafCount_; }

  // Estimate for the whole tree at p (the root's cluster estimate, or the exact leaf importance
  // when the tree holds one light).
  template <typename Leaf>
  double RootImportance(const Vec3d& p, const Vec3d* n, Leaf&& leaf) const {
    return Importance(0, p, n, leaf);
  }

  // Picks a light with u in [0, 1); false when the walk reaches a node whose children both have
  // zero importance (no light below it can light p). *pmf is the probability of the light given
  // the tree.
  template <typename Leaf>
  bool Sample(const Vec3d& p, const Vec3d* n, double u, Leaf&& leaf, uint32_t* light,
              double* pmf) const {
    uint32_t node = 0;
    double prob = 1;
    while (!nodes_[node].leaf) {
      const Node& nd = nodes_[node];
      const double i0 = Importance(nd.child0, p, n, leaf);
      const double i1 = Importance(nd.child1, p, n, leaf);
      const double sum = i0 + i1;
      if (!(sum > 0)) return false;
      const double p0 = i0 / sum;
      if (u < p0) {
        u = std::min(u / p0, kOneMinusEpsilon);
        prob *= p0;
        node = nd.child0;
      } else {
        u = std::min((u - p0) / (1 - p0), kOneMinusEpsilon);
        prob *= i1 / sum;
        node = nd.child1;
      }
    }
    if (!(prob > 0)) return false;
    *light = nodes_[node].index;
    *pmf = prob;
    return true;
  }

  // The probability that Sample picks `light` at p. Precondition: `light` is in the tree.
  template <typename Leaf>
  double Pmf(uint32_t light, const Vec3d& p, const Vec3d* n, Leaf&& leaf) const {
    const Path& path = pathOfLight_[light];
    uint32_t node = 0;
    double prob = 1;
    for (uint32_t level = 0; level < path.depth; ++level) {
      const Node& nd = nodes_[node];
      const double i0 = Importance(nd.child0, p, n, leaf);
      const double i1 = Importance(nd.child1, p, n, leaf);
      const double sum = i0 + i1;
      if (!(sum > 0)) return 0;
      const bool right = (path.bits >> level) & 1;
      prob *= (right ? i1 : i0) / sum;
      node = right ? nd.child1 : nd.child0;
    }
    return prob;
  }

 private:
  struct Node {
    Vec3d lo, hi;
    double weight = 0;
    // Floor on d^2: the smallest of its lights' own floors, raised to their spacing squared.
    double clamp = 0;
    bool everyDirection = true;  // the cone below bounds nothing
    Vec3d axis;
    double cosO = -1, sinO = 0, cosE = 0;
    Vec3d centre;       // of the box
    double radius = 0;  // half the box diagonal
    bool leaf = false;
    uint32_t child0 = 0, child1 = 0;  // inner nodes
    uint32_t index = 0;               // leaves: the light
  };
  struct Path {
    uint64_t bits = 0;   // bit k: 1 when the walk goes to child1 at depth k
    uint32_t depth = 0;  // number of inner nodes on the way (< 64)
  };

  template <typename Leaf>
  double Importance(uint32_t node, const Vec3d& p, const Vec3d* n, Leaf& leaf) const {
    const Node& nd = nodes_[node];
    if (nd.leaf) return leaf(nd.index);
    if (n) {
      // The box corner farthest along n: the whole box is on or below the plane iff it is.
      const Vec3d support{n->x > 0 ? nd.hi.x : nd.lo.x, n->y > 0 ? nd.hi.y : nd.lo.y,
                          n->z > 0 ? nd.hi.z : nd.lo.z};
      if (Dot(support - p, *n) <= 0) return 0;
    }
    // Halfway between the nearest and the farthest the lights can be: 1/d^2 over a cluster next
    // to p ranges widely (demo room with 64 small ceiling lights: the distance to the centre gave
    // 1.8x the variance of the linear choice, this 0.8x).
    const Vec3d toNear = Max(Max(nd.lo - p, p - nd.hi), Vec3d{});
    const Vec3d toFar = Max(nd.hi - p, p - nd.lo);
    double cosP = 1;
    if (!nd.everyDirection) {
      const Vec3d v = p - nd.centre;
      const double d2 = LengthSquared(v);
      const double r2 = nd.radius * nd.radius;
      if (d2 > r2) {
        // theta_w: the angle between the axis and the centre's direction to p; theta_b: the angle
        // the bounding sphere subtends at p. cos(max(0, theta_w - theta_o - theta_b)).
        const double d = std::sqrt(d2);
        const double cosW = Dot(nd.axis, v) / d;
        const double sinW = std::sqrt(std::max(0.0, 1 - cosW * cosW));
        const double sinB = nd.radius / d, cosB = std::sqrt(std::max(0.0, 1 - sinB * sinB));
        const bool insideO = cosW > nd.cosO;
        const double cosX = insideO ? 1 : cosW * nd.cosO + sinW * nd.sinO;
        const double sinX = insideO ? 0 : sinW * nd.cosO - cosW * nd.sinO;
        cosP = cosX > cosB ? 1 : cosX * cosB + sinX * sinB;
        if (cosP <= nd.cosE - 1e-9) return 0;
        cosP = std::max(cosP, 0.0);
      }
    }
    return cosP * nd.weight * 0.5 *
           (1 / std::max(LengthSquared(toNear), nd.clamp) +
            1 / std::max(LengthSquared(toFar), nd.clamp));
  }

  uint32_t Build(std::vector<Item>& items, size_t begin, size_t end, uint64_t bits, uint32_t depth);

  std::vector<Node> nodes_;  // nodes_[0] is the root
  size_t leafCount_ = 0;
  std::vector<Path> pathOfLight_;  // by light index (entries of lights not in the tree unused)
};

}  // namespace probebake
