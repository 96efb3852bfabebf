// Material stability of a body under homogeneous compression.
//
// A compressed pair spring of force f and length l resists a sideways move of one end with the
// stiffness -f / l: negative (a compressed column buckles). A conical card stiffens steeply as its
// coils bottom out, so under a large uniaxial compression its springs along the load carry a
// stress that can outgrow everything that resists shear (the other spring families and the
// neo-Hookean shear term). Past that strain the homogeneous state of the material is no longer
// stable against short waves: it loses strong ellipticity, and a body compressed beyond it
// buckles in zig-zag layers between the plates instead of shortening uniformly (a discrete model
// finds no equilibrium near it, and its force curve is no result).
//
// The check is the one a continuum code makes of a fitted hyperelastic law (a material
// evaluation's stability limit), made on the body itself: the Cauchy-Born energy density of the
// body deformed affinely, W(F) = (sum over springs of their energy + sum over elements of their
// volume and shear energy) / V0, its tangent A = d2W / dF dF, and the acoustic tensor
// Q(n)_ij = A_iAjB n_A n_B. Strong ellipticity holds while Q(n) is positive definite for every
// unit n. Along uniaxial compression F = diag(lambda_1, lambda_2, 1 - e) (in the frame of the
// load axis) with the lateral stretches that leave the lateral faces free, the onset is the
// smallest e at which it fails. The average over a body is what the check sees: a body of one
// material everywhere (the scenes' cards) loses it where its material does.
//
// Core only: no I/O, no logging; allocates (a load-time and calibration check, never in a step).
#pragma once

#include <Eigen/Core>

#include "core/model.h"

namespace conica {

using Mat9 = Eigen::Matrix<double, 9, 9>;

// W(F) per rest volume (J/m^3), its first Piola stress P (Pa; P(i, A) = dW / dF(i, A)) and
// tangent A (Pa; A(3 A + i, 3 B + j) = d2W / dF(i, A) dF(j, B), i.e. F flattened column-major).
// Card damping and Maxwell branches are left out (the long-term, elastic response); the
// Gauss-point spread term is zero under any affine deformation and is left out. Precondition:
// the body has elements (V0 > 0) and det F > 0.
struct HomogenisedState {
  double energy = 0;
  Mat3 stress = Mat3::Zero();
  Mat9 tangent = Mat9::Zero();
};
HomogenisedState homogenised_state(const Model& model, const Mat3& F);

// The smallest eigenvalue (Pa) of the acoustic tensor Q(n) over unit n, and the n and
// polarisation (unit) where it is reached: searched over `directions` directions of a
// hemisphere, then refined by a pattern search. A tangent with the symmetry of a square prism
// about z (unchanged by x -> -x, y -> -y and x <-> y to 1e-12 of its size: a cubic lattice
// cell compressed along an axis) is scanned over the eighth of those directions with
// 0 <= y <= x, whose images cover the rest.
struct SoftestWave {
  double modulus = 0;
  Vec3 normal = Vec3::UnitZ();
  Vec3 polarisation = Vec3::UnitX();
};
SoftestWave softest_wave(const Mat9& tangent, int directions = 2000);

struct CompressionStability {
  // The engineering strain along the axis at which strong ellipticity is first lost (to 1e-4);
  // -1: not up to max_strain.
  double onset_strain = -1;
  // The softest wave there (or, with no onset, at max_strain or the last strain reached).
  SoftestWave wave;
  double checked_to = 0;  // the strain the path was followed to (< max_strain: the lateral
                          // stretch could not be solved past it, e.g. a spring past its solid
                          // height with no stiffness cap)
  Vec3 lateral_stretch = Vec3::Ones();  // at onset_strain (or checked_to), axis frame
};
// Follows uniaxial compression along the unit `axis` from 0 to max_strain (in (0, 1)) in steps
// of `step`, the lateral stretches solved (Newton) for zero lateral normal stress.
CompressionStability uniaxial_compression_stability(const Model& model, const Vec3& axis,
                                                    double max_strain, double step = 0.01);

// The softest wave at uniaxial compression `strain` along `axis` alone (the lateral stretches
// followed from rest in `steps` steps): a cheap test of one strain for fits. Modulus NaN when the
// path cannot be solved. `stretch` (optional, axis frame): in, a solution at this strain for a
// nearby model (a fit's last card), from which the point is solved directly (the path from rest
// when that fails); out, the stretches solved (unchanged when none).
SoftestWave uniaxial_softest_wave(const Model& model, const Vec3& axis, double strain,
                                  int steps = 10, int directions = 400, Vec3* stretch = nullptr);

// Stability of one equilibrium of the whole body, boundary included: its stiffness K = -df/dx on
// the free axes (every spring's exact tangent, a compressed one's negative transverse stiffness
// -f / l included; the element terms; plates, probes and hard stops as the force pass applies
// them), by central differences of compute_forces with the nodes perturbed in groups that share
// no neighbour (a distance-2 colouring of the mesh graph). The equilibrium is stable while K is
// positive definite: a material that keeps strong ellipticity can still lose it as a body, at
// its free surface (Biot) or where its discretisation is coarse, and this sees that too.
// Velocities are taken as zero (the elastic stiffness only).
struct EquilibriumStability {
  // Eigenvalues of K below -shift, counted from the signs of an LDL^T factor of K + shift I
  // (Sylvester's law of inertia): the modes along which the body's energy falls.
  int negative = 0;
  // 1e-5 x the median diagonal entry of K (N/m): rigid motions the boundary leaves free (a body
  // between frictionless plates turns about their normal at no cost) sit at 0 +- round-off and
  // must not count as unstable.
  double shift = 0;
  bool factored = false;  // the factor succeeded (negative is meaningful)
};
struct State;
EquilibriumStability equilibrium_stability(const Model& model, const State& state);

}  // namespace conica
