// Viscoelastic experiments on a body between plates (the paper's Figure 9): cyclic loading
// (hysteresis), force relaxation under a held displacement and creep under a held load. The
// body's springs carry a Maxwell branch (SpringCard::maxwell_k, maxwell_tau): per spring a
// standard linear solid, P = law(delta) + k_m (delta - e_m), e_m relaxing to delta with tau.
// When every spring has the same k_m / K0 and stays in its linear phase, the whole body is a
// standard linear solid with the same ratio: relaxation time tau, retardation (creep) time
// tau (1 + k_m / K0), instantaneous / long-term stiffness 1 + k_m / K0.
#pragma once

#include <functional>
#include <vector>

#include "core/model.h"

namespace conica::lab {

struct PlateHistory {
  std::vector<double> time;          // s
  std::vector<double> displacement;  // m, plate travel from first contact
  std::vector<double> force;         // N, on the plate, compression positive
};

// Moves plane 0 along the program u(t) (m of travel from first contact, t in s) for `duration`
// with the model's integrator and time step; records every step. The plate penalty is raised as
// in compression_curve.
PlateHistory displacement_program(const Model& model, const std::function<double(double)>& u,
                                  double duration);

// Load control: the plate follows the target force F(t) (N) by a per-step controller on its
// travel, u += gain (F(t) - F) / k, with k the body's instantaneous stiffness measured by a small
// trial step at the start. Records every step.
PlateHistory force_program(const Model& model, const std::function<double(double)>& force,
                           double duration, double gain = 0.5);

// Time constant of an exponential approach y(t) -> y_inf over t >= t0 (a log-linear fit of
// |y - y_inf| between 90 % and 5 % of its first value), with y_inf the last sample.
double decay_time(const std::vector<double>& t, const std::vector<double>& y, double t0);

// Area enclosed by the loop u -> F over samples [begin, end) (J), positive for a loop run
// clockwise in (u, F) (energy dissipated).
double loop_area(const std::vector<double>& u, const std::vector<double>& f, size_t begin,
                 size_t end);

}  // namespace conica::lab
