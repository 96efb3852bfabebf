// The conical spring load-deflection law (paper section 2, restated in docs/conical-law.md).
//
// A constant-pitch conical spring with card (G, d, D1, D2, L0, n_a). Units are those of the
// card: with G in Pa and lengths in m, loads come out in N and stiffness in N/m. Nothing here
// does I/O, logs, throws inside evaluation, or allocates after construction.
//
//   r1 = D1/2, r2 = D2/2
//   Ls = sqrt(max(0, (n_a d)^2 - (r2 - r1)^2))          solid height, eq. (3)
//   Type I (non-telescopic) if r2 - r1 < n_a d, Type II (telescopic, Ls = 0) otherwise
//   S  = L0 - Ls (stroke),  g = S / n_a (gap per unit coil)
//   A  = G d^4 g / 64,  c = 16 n_a / (G d^4 (r2 - r1))
//   r_t(P) = (A / P)^(1/3): coils with radius r > r_t are bottomed
//
//   linear    (r_t >= r2):       delta = P / K0,  K0 = G d^4 (r2 - r1) / (16 n_a (r2^4 - r1^4))
//   nonlinear (r1 < r_t < r2):   delta = c P (r_t^4 - r1^4) + S (r2 - r_t) / (r2 - r1)
//                                      = c A (4 r2 - 3 r_t - r1^4 / r_t^3)
//   solid     (delta = S):       P = Ps = A / r1^3, tangent stiffness infinite
//   tangent stiffness (all phases): k_t = 1 / (c (r_t^4 - r1^4)), r_t clamped to r2
//
// Tension (delta < 0): no coil can bottom, so the spring is linear with K0 (documented choice).
//
// Regularisation for simulation: a fixed-step integrator cannot follow an infinite stiffness.
// With a stiffness cap k_cap (> K0), the law is followed exactly until k_t reaches k_cap at
// deflection delta_cap, and continues beyond it as a straight line of slope k_cap (C1, also
// past the solid height). k_cap = infinity gives the exact law, which is finite only up to S.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace conica {

// A conical spring card. Lengths in the card's unit of length (SI: m), G in its unit of
// stress (SI: Pa).
struct ConicalCard {
  double G = 0;    // shear modulus of the wire
  double d = 0;    // wire diameter
  double D1 = 0;   // smallest mean coil diameter
  double D2 = 0;   // largest mean coil diameter
  double L0 = 0;   // free length
  double n_a = 0;  // number of active coils
};

// Returns an empty string when the card is valid, otherwise a message naming the parameter and
// the constraint it broke (d <= 0, D1 >= D2, n_a <= 0, L0 <= solid height, NaN, ...).
std::string validate(const ConicalCard& card);

enum class Phase : std::uint8_t { kTension = 0, kLinear = 1, kNonlinear = 2, kSolid = 3 };
const char* phase_name(Phase p);

struct LawSample {
  double force = 0;      // load P (compression positive)
  double stiffness = 0;  // tangent stiffness dP/d delta
  Phase phase = Phase::kLinear;
};

// Derived constants of a valid card. Immutable; cheap to copy except for the inverse table.
class ConicalLaw {
 public:
  // Precondition: validate(card).empty(). `stiffness_cap` <= 0 or infinite means exact law.
  explicit ConicalLaw(const ConicalCard& card,
                      double stiffness_cap = std::numeric_limits<double>::infinity());

  const ConicalCard& card() const { return card_; }
  bool telescopic() const { return telescopic_; }  // Type II
  double solid_height() const { return Ls_; }       // Ls
  double stroke() const { return S_; }              // S = L0 - Ls
  double k0() const { return K0_; }                 // linear-phase stiffness
  double transition_load() const { return Pt_; }    // Pt = A / r2^3
  double transition_deflection() const { return dt_; }
  double solid_load() const { return Ps_; }  // Ps = A / r1^3
  double stiffness_cap() const { return kcap_; }
  double cap_deflection() const { return dcap_; }  // where k_t reaches the cap (S if none)

  // Eq. (10)-(11): deflection under compressive load P >= 0 (P < 0: tension, linear).
  // Loads above Ps return S.
  double deflection(double P) const;
  // Tangent compliance d delta / dP at load P.
  double compliance(double P) const;

  // The inverse, P(delta), with tangent stiffness. Exact up to the cap: the bottoming radius is
  // found by a safeguarded Newton iteration to machine precision. Use for reference work.
  LawSample evaluate_exact(double delta) const;
  // Same law from a precomputed table plus one Newton correction: relative error <= 1e-9 in force
  // and stiffness (tests/core/conical_test.cc sweeps it, extreme tapers included).
  LawSample evaluate(double delta) const;

  // evaluate() over arrays: force[i] and stiffness[i] for deflection[i], i < n; the arrays must
  // not overlap. Bit for bit the values of evaluate() (the cap-free law returns force Ps and
  // infinite stiffness at and past the solid height). The simulation's inner loop: it works in
  // chunks of kBatchChunk springs; a chunk entirely in tension or the linear phase costs what a
  // Hooke spring costs, any other chunk runs a branch-free pass that GCC vectorises (with gathers
  // on AVX2 / AVX-512) followed by a pass that selects the phase. No allocation.
  void evaluate_batch(const double* __restrict deflection, double* __restrict force,
                      double* __restrict stiffness, int n) const;

  // Strain energy, the integral of the (regularised) force from 0 to delta.
  double energy(double delta) const;

  // Paper's eq. (11) form in diameters with n the number of unbottomed coils: kept to check
  // it against the radius form above.
  double deflection_eq11(double P, double n) const;
  // The paper's printed closed-form inverse, eq. (12)-(19), evaluated literally as printed.
  // Returns NaN where the printed expression is not real. Kept only to show that it does not
  // invert eq. (11) (see tests).
  double load_eq12_as_printed(double delta) const;

 private:
  double radius_from_deflection(double delta) const;  // exact nonlinear-phase solve
  double gap_from_s(double s) const;  // r_t - r1 from s = sqrt(S - delta)
  double energy_at_radius(double rt) const;  // energy from 0 to deflection at radius rt

  ConicalCard card_;
  bool telescopic_ = false;
  double r1_ = 0, r2_ = 0, Ls_ = 0, S_ = 0, A_ = 0, c_ = 0, K0_ = 0;
  double Pt_ = 0, dt_ = 0, Ps_ = 0, r1p4_ = 0;
  double kcap_ = std::numeric_limits<double>::infinity();
  double kcap_force_ = 0;  // slope used for the force past the cap (0 when the cap is infinite)
  double dcap_ = 0, Pcap_ = 0, rcap_ = 0, Ecap_ = 0, Et_ = 0;

  // Inverse table of x = r_t - r1 over s = sqrt(S - delta) in [0, s_max], where r_t(s) is smooth
  // (it has a square-root singularity in delta at the solid height). Cubic Hermite per segment,
  // stored as power-basis coefficients of the local variable t in [0, 1], structure of arrays:
  // table_[m * kTableSegments + i] is coefficient m (of t^m) of segment i, so that the array loop
  // gathers each coefficient with one vector instruction.
  static constexpr int kTableSegments = 256;
  static constexpr int kBatchChunk = 256;  // springs per pass of evaluate_batch
  double s_max_ = 0, inv_h_ = 0, sqrt_cA_ = 0;
  std::vector<double> table_;  // (4 x kTableSegments)
};

}  // namespace conica
