// Deterministic quadrature on [-1, 1] and on the unit sphere, for exact projections of
// polynomial functions (orthonormality checks, reference projections, analytic skies).
//
// The sphere rule is a product: Gauss–Legendre in z = cos θ times equally spaced φ. With nz
// Gauss–Legendre nodes and nphi angles it integrates exactly (up to rounding) every spherical
// polynomial of degree <= min(2 nz - 1, nphi - 1), in particular every product Y_i Y_j with
// l_i + l_j <= that degree. Directions follow sh_basis.h: polar axis +Z, φ from +X toward +Y.
#pragma once

#include <vector>

#include "probebake/math/vec3.h"

namespace probebake {

struct QuadratureRule1D {
  std::vector<double> nodes;    // ascending, in (-1, 1)
  std::vector<double> weights;  // positive, summing to 2
};

// The n-point Gauss–Legendre rule on [-1, 1] (n >= 1, checked): exact for polynomials of degree
// <= 2n - 1. Nodes by Newton's iteration on P_n to full double precision.
QuadratureRule1D GaussLegendreRule(int n);

struct SphereQuadratureNode {
  Vec3d direction;  // unit
  double weight;    // solid angle, sr; all weights sum to 4π
};

// Product rule with nz Gauss–Legendre nodes in z and nphi equally spaced φ (both >= 1, checked).
std::vector<SphereQuadratureNode> SphereProductQuadrature(int nz, int nphi);

// The smallest product rule exact for spherical polynomials of degree <= degree (>= 0):
// nz = floor(degree/2) + 1, nphi = degree + 1.
std::vector<SphereQuadratureNode> SphereQuadratureForDegree(int degree);

}  // namespace probebake
