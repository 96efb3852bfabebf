// A continuum reference for indentation of an elastic layer bonded to a rigid base (Hayes, Keer,
// Herrmann & Mockros 1972, J. Biomech. 5:541-551): a rigid frictionless axisymmetric punch on a
// linear elastic layer of Young's modulus E, Poisson ratio nu and thickness h, all displacements
// zero at the base. Computed here from first principles (the layer's surface Green's function in
// Hankel space, a Fredholm equation of the second kind solved by Nystrom), not from Hayes' table.
// Small strain, small indentation; core only, no I/O, no logging.
//
// Flat punch of radius a pressed a depth w (Sneddon's half-space value times Hayes' kappa):
//   P = 2 a E w kappa(a/h, nu) / (1 - nu^2),  kappa -> 1 as a/h -> 0.
// Thin-layer limits (a/h >> 1): compressible, the layer under the punch in uniaxial strain,
// P -> pi a^2 w M / h with M = E (1 - nu) / ((1 + nu)(1 - 2 nu)); incompressible (nu = 1/2),
// squeeze flow under the shear-free punch over the no-slip base, P -> pi E w a^4 / (8 h^3).
//
// Rigid sphere of radius R with contact radius a (a << R, pressure bounded at the contact edge):
//   w = depth_factor * a^2 / R,  P = force_factor * 4 E a^3 / (3 R (1 - nu^2))  (Hertz times).
// Every routine refuses bad input (nu outside (-1, 1/2], a/h <= 0, lengths or E <= 0, anything
// non-finite) by throwing std::invalid_argument naming the argument. The cost grows as (a/h)^3:
// milliseconds up to a/h = 20, half a second at a/h = 100, the largest accepted (kMaxAOverH).
#pragma once

namespace conica::lab {

// Largest a/h accepted: past it the thin-layer asymptotes above are the reference (within
// 0.25 % for nu = 0.3, 6 % for nu = 1/2 at a/h = 100; see the test).
inline constexpr double kMaxAOverH = 100;

// K(t): the layer's surface compliance to a normal surface pressure of wavenumber xi = t / h
// over the half-space's (w^ = 2 (1 - nu^2) / E p^ K(xi h) / xi). 0 at t = 0, -> 1 as t -> inf.
double bonded_layer_compliance(double t, double nu);

// Hayes' kappa for the flat punch. `refine` (1 to 4) multiplies every quadrature's number of
// points: 1 is converged to about 1e-10 relative, 2 is there to show it (cost ~ refine^3).
double bonded_layer_kappa(double a_over_h, double nu, int refine = 1);

// Force (N) on a flat punch of radius a (m) pressed w (m, >= 0) into a layer of thickness h (m),
// Young's modulus E (Pa), Poisson ratio nu.
double bonded_layer_punch_force(double a, double h, double E, double nu, double w);

struct SphereFactors {
  double depth_factor = 1;  // w / (a^2 / R); 1 on a half-space
  double force_factor = 1;  // P / (4 E a^3 / (3 R (1 - nu^2))); 1 on a half-space
};
// Rigid frictionless sphere, contact radius a over layer thickness h.
SphereFactors bonded_layer_sphere(double a_over_h, double nu, int refine = 1);

}  // namespace conica::lab
