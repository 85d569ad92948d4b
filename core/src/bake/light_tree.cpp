#include "light_tree.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "probebake/base/check.h"

namespace probebake {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct Cone {
  Vec3d axis;
  double thetaO = kPi;  // >= pi: every direction
  double thetaE = 0;
};

// The smallest cone (of this construction) holding both: pbrt-v4's DirectionCone::Union.
Cone Union(const Cone& a, const Cone& b) {
  Cone out;
  out.thetaE = std::max(a.thetaE, b.thetaE);
  if (a.thetaO >= kPi || b.thetaO >= kPi) return out;
  const double thetaD = AngleBetween(a.axis, b.axis);
  if (std::min(thetaD + b.thetaO, kPi) <= a.thetaO) return {a.axis, a.thetaO, out.thetaE};
  if (std::min(thetaD + a.thetaO, kPi) <= b.thetaO) return {b.axis, b.thetaO, out.thetaE};
  const double thetaO = (a.thetaO + thetaD + b.thetaO) / 2;
  if (thetaO >= kPi) return out;
  const Vec3d k = Cross(a.axis, b.axis);
  const double kLength = Length(k);
  if (!(kLength > 0)) return out;
  // Rotate a's axis towards b's by thetaO - thetaA about k (Rodrigues; k is perpendicular to it).
  const double thetaR = thetaO - a.thetaO;
  const Vec3d kUnit = k / kLength;
  out.axis = Normalize(a.axis * std::cos(thetaR) + Cross(kUnit, a.axis) * std::sin(thetaR));
  out.thetaO = thetaO;
  return out;
}

}  // namespace

LightTree::LightTree(std::vector<Item> items) {
  PB_CHECK(!items.empty());
  PB_CHECK_LT(items.size(), size_t{std::numeric_limits<uint32_t>::max()});
  leafCount_ = items.size();
  uint32_t maxLight = 0;
  for (const Item& it : items) maxLight = std::max(maxLight, it.light);
  pathOfLight_.resize(size_t(maxLight) + 1);
  nodes_.reserve(2 * items.size() - 1);
  Build(items, 0, items.size(), 0, 0);
}

uint32_t LightTree::Build(std::vector<Item>& items, size_t begin, size_t end, uint64_t bits,
                          uint32_t depth) {
  const uint32_t index = uint32_t(nodes_.size());
  nodes_.emplace_back();
  Node node;
  node.lo = items[begin].lo;
  node.hi = items[begin].hi;
  node.clamp = items[begin].clamp;
  Vec3d centroidLo = (items[begin].lo + items[begin].hi) * 0.5, centroidHi = centroidLo;
  Cone cone{items[begin].axis, items[begin].thetaO, items[begin].thetaE};
  for (size_t i = begin; i < end; ++i) {
    cone = Union(cone, {items[i].axis, items[i].thetaO, items[i].thetaE});
    node.lo = Min(node.lo, items[i].lo);
    node.hi = Max(node.hi, items[i].hi);
    node.weight += items[i].weight;
    node.clamp = std::min(node.clamp, items[i].clamp);
    const Vec3d c = (items[i].lo + items[i].hi) * 0.5;
    centroidLo = Min(centroidLo, c);
    centroidHi = Max(centroidHi, c);
  }
  // A cluster's lights are not all at its nearest point: floor the near distance at about the
  // spacing of n lights spread through the box (half-diagonal r): r / n^(1/3).
  const double n = double(end - begin);
  node.clamp = std::max(node.clamp, 0.25 * LengthSquared(node.hi - node.lo) / std::cbrt(n * n));
  node.centre = (node.lo + node.hi) * 0.5;
  node.radius = 0.5 * Length(node.hi - node.lo);
  if (cone.thetaO < kPi && cone.thetaO + cone.thetaE < kPi) {
    node.everyDirection = false;
    node.axis = cone.axis;
    node.cosO = std::cos(cone.thetaO);
    node.sinO = std::sin(cone.thetaO);
    node.cosE = std::cos(cone.thetaE);
  }
  if (end - begin == 1) {
    node.leaf = true;
    node.index = items[begin].light;
    pathOfLight_[node.index] = {bits, depth};
    nodes_[index] = node;
    return index;
  }
  // Median split along the widest extent of the lights' centres; ties broken by light index so
  // the tree does not depend on the input order's accidents (it is built from the scene, in order,
  // anyway).
  const Vec3d extent = centroidHi - centroidLo;
  const int axis =
      extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
  const size_t mid = begin + (end - begin) / 2;
  std::nth_element(items.begin() + begin, items.begin() + mid, items.begin() + end,
                   [axis](const Item& a, const Item& b) {
                     const double ca = a.lo[axis] + a.hi[axis], cb = b.lo[axis] + b.hi[axis];
                     return ca < cb || (ca == cb && a.light < b.light);
                   });
  PB_CHECK_LT(depth, 63u);
  node.child0 = Build(items, begin, mid, bits, depth + 1);
  node.child1 = Build(items, mid, end, bits | (uint64_t{1} << depth), depth + 1);
  nodes_[index] = node;
  return index;
}

}  // namespace probebake
