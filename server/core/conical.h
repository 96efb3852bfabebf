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
// Pre-compression (card.precompression = delta0, 0 <= delta0 < S): the spring is installed in the
// body already compressed by delta0 (a rest length L0 - delta0), its preload balanced by the body,
// so the body feels
//   F(delta) = P(delta0 + delta) - P(delta0),   k_t(delta) = P'(delta0 + delta),
// zero at the body's rest shape (which stays an equilibrium) and stiffening from the start when
// delta0 is past delta_t. delta is the body's deflection (from its rest shape); the spring's own
// is delta0 + delta. Tension: from delta = 0 down to -delta0 the spring extends back along its law
// (the preload is released); beyond, the spring itself is stretched and is linear with K0 as above,
// so F(delta) = K0 (delta0 + delta) - P(delta0) there (C1 at -delta0: the plain law is linear on
// both sides of its free length). In short, the plain law shifted by delta0 in both axes.
// delta0 = 0 is the plain law. The accessors below (stroke, transition, cap, K0) describe the
// spring itself, in its own deflection; the body reaches the solid height at delta = S - delta0.
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
  double G = 0;               // shear modulus of the wire
  double d = 0;               // wire diameter
  double D1 = 0;              // smallest mean coil diameter
  double D2 = 0;              // largest mean coil diameter
  double L0 = 0;              // free length
  double n_a = 0;             // number of active coils
  double precompression = 0;  // delta0: initial deflection of the installed spring (unit of
                              // length, SI: m), 0 <= delta0 < S; 0: the plain law
};

// Returns an empty string when the card is valid, otherwise a message naming the parameter and
// the constraint it broke (d <= 0, D1 >= D2, n_a <= 0, L0 <= solid height, precompression < 0 or
// >= stroke, NaN, ...).
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
  double solid_height() const { return Ls_; }      // Ls
  double stroke() const { return S_; }             // S = L0 - Ls
  double k0() const { return K0_; }                // linear-phase stiffness
  double transition_load() const { return Pt_; }   // Pt = A / r2^3
  double transition_deflection() const { return dt_; }
  double solid_load() const { return Ps_; }  // Ps = A / r1^3
  double stiffness_cap() const { return kcap_; }
  double cap_deflection() const { return dcap_; }  // where k_t reaches the cap (S if none)
  // Pre-compression: delta0, the preload P(delta0) (what the body balances at rest; the
  // table-based value that evaluate() subtracts), the tangent stiffness at rest k_t(delta0)
  // (= K0 for delta0 <= delta_t) and the body's room to the solid height, S - delta0.
  double precompression() const { return d0_; }
  double preload() const { return F0_; }
  double rest_stiffness() const { return k_rest_; }
  double remaining_stroke() const { return S_ - d0_; }

  // Eq. (10)-(11): deflection under compressive load P >= 0 (P < 0: tension, linear).
  // Loads above Ps return S. With a pre-compression: the body's deflection under the load P
  // added to the preload, deflection(P + P(delta0)) - delta0.
  double deflection(double P) const;
  // Tangent compliance d delta / dP at load P (on top of the preload).
  double compliance(double P) const;

  // The inverse, P(delta), with tangent stiffness. Exact up to the cap: the bottoming radius is
  // found by a safeguarded Newton iteration to machine precision. Use for reference work.
  // delta is the body's deflection: with a pre-compression the force is P(delta0 + delta) -
  // P(delta0) and the phase that of the spring at delta0 + delta.
  LawSample evaluate_exact(double delta) const;
  // Same law from a precomputed table plus one Newton correction: relative error <= 1e-9 in force
  // and stiffness (tests/core/conical_test.cc sweeps it, extreme tapers included). With a
  // pre-compression it is the plain law's evaluate(delta0 + delta) minus preload() (stiffness bit
  // for bit, force up to the rounding of that subtraction).
  LawSample evaluate(double delta) const;

  // evaluate() over arrays: force[i] and stiffness[i] for deflection[i], i < n; the arrays must
  // not overlap. Bit for bit the values of evaluate() (with a pre-compression: the stiffness bit
  // for bit, the force within 1 ulp, the preload's subtraction being fused or not with the law's
  // last multiplication as the compiler chooses per loop; the cap-free law returns force Ps and
  // infinite stiffness at and past the solid height). The simulation's inner loop: it works in
  // chunks of kBatchChunk springs; a chunk entirely in tension or the linear phase costs what a
  // Hooke spring costs, any other chunk runs a branch-free pass that GCC vectorises (with gathers
  // on AVX2 / AVX-512) followed by a pass that selects the phase. No allocation.
  void evaluate_batch(const double* __restrict deflection, double* __restrict force,
                      double* __restrict stiffness, int n) const;

  // Strain energy, the integral of the (regularised) force from 0 to delta. With a
  // pre-compression: E(delta0 + delta) - E(delta0) - P(delta0) delta of the plain law (the work
  // of the body's force, zero at rest; it loses relative precision for |delta| << delta0).
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
  double gap_from_s(double s) const;                  // r_t - r1 from s = sqrt(S - delta)
  double energy_at_radius(double rt) const;           // energy from 0 to deflection at radius rt
  // The plain law (no pre-compression) at the spring's own deflection.
  LawSample evaluate_plain(double delta) const;
  LawSample evaluate_exact_plain(double delta) const;
  double energy_plain(double delta) const;
  template <bool kShifted>
  void evaluate_batch_impl(const double* __restrict deflection, double* __restrict force,
                           double* __restrict stiffness, int n) const;

  ConicalCard card_;
  bool telescopic_ = false;
  double r1_ = 0, r2_ = 0, Ls_ = 0, S_ = 0, A_ = 0, c_ = 0, K0_ = 0;
  double Pt_ = 0, dt_ = 0, Ps_ = 0, r1p4_ = 0;
  double kcap_ = std::numeric_limits<double>::infinity();
  double kcap_force_ = 0;  // slope used for the force past the cap (0 when the cap is infinite)
  double dcap_ = 0, Pcap_ = 0, rcap_ = 0, Ecap_ = 0, Et_ = 0;
  // Pre-compression: delta0, P(delta0) from the table (evaluate, batch) and exact
  // (evaluate_exact, energy, deflection), E(delta0), k_t(delta0).
  double d0_ = 0, F0_ = 0, F0x_ = 0, E0_ = 0, k_rest_ = 0;

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
