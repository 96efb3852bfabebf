// conica-lab validate: standard small-strain cases on the shipped EF30 scenes
// (configs/validation), each against a closed-form continuum result a reader can check, with
// refinement studies. Prints a Markdown table (docs/validation.md) and writes the curves the
// figure draws into --out-dir.
//
// The continuum moduli of a scene are its isotropic (Voigt) estimates: K = (C11 + 2 C12) / 3 +
// kappa, G = (C11 - C12 + 3 C44) / 5 + mu (lab/calibration.h), E = 9 K G / (3 K + G),
// nu = (3 K - 2 G) / (2 (3 K + G)), E* = E / (1 - nu^2).
//  - uniaxial: frictionless compression of the cylinder, F / (A strain) = E.
//  - Gent and Lindley (1959): a bonded incompressible block of shape factor S (the loaded area over
//    the free one: R / (2 h) for a cylinder, a / (4 h) for a square prism of side a) has
//    E_c = E (1 + 2 S^2), the same coefficient for circular and square sections: compared as the
//    ratio of the bonded to the frictionless modulus of the same body, which does not depend on
//    the estimate of E (compressibility lowers it). On the cylinder and on the 30 mm cube.
//  - Sneddon (1965) / Boussinesq: a rigid frictionless flat punch of radius a pressed d into a
//    half-space: F = 2 a E* d, and the surface outside it sinks w(r) = (2 d / pi) asin(a / r).
//    The block is 60 x 60 x 30 mm bonded to its base (h / a = 6), so the finite layer stiffens the
//    punch a little over the half-space value.
//  - Hayes et al. (1972): the same punch on layers 30 to 5 mm thick bonded to a rigid base,
//    F = 2 a E* d kappa(a / h, nu), kappa from the layer's integral equation solved here
//    (lab/layer_indentation.h); also as the ratio to the 30 mm layer's force, the thickness
//    correction alone, which does not depend on how the lattice resolves the punch's edge.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "app/lab/lab.h"
#include "core/contact.h"
#include "core/step.h"
#include "io/mesh_repair.h"
#include "io/scene.h"
#include "lab/calibration.h"
#include "lab/layer_indentation.h"
#include "lab/quasi_static.h"

namespace conica::lab {

namespace {

struct Moduli {
  double E = 0, nu = 0, K = 0, G = 0;
};
Moduli moduli(const BodySpec& spec) {
  const LatticeModuli lm = lattice_moduli(spec.groups);
  Moduli m;
  m.K = (lm.c11 + 2 * lm.c12) / 3 + spec.bulk_modulus;
  m.G = lattice_shear(lm) + spec.shear_modulus;
  m.E = 9 * m.K * m.G / (3 * m.K + m.G);
  m.nu = (3 * m.K - 2 * m.G) / (2 * (3 * m.K + m.G));
  return m;
}

// Force (N) at plate travel `strain` x height, quasi-static, one increment.
bool compress_force(BodySpec spec, bool bonded, double strain, double* force, double* area,
                    long* nodes, std::string* error) {
  ensure_top_plate(&spec);
  if (bonded) {
    if (std::string e = bond_compression_plates(&spec); !e.empty()) return *error = e, false;
  }
  Model m;
  if (std::string e = build_model(spec, &m); !e.empty()) return *error = e, false;
  m.planes[0].stiffness = std::max(m.planes[0].stiffness, rigid_plate_stiffness(m, false));
  QuasiStaticOptions o;
  o.samples = 1;
  o.tolerance = 1e-6;
  QuasiStaticStats st;
  const Curve c =
      quasi_static_curve(m, plate_load(m), plate_reaction(), strain * plate_height(m), o, &st);
  if (st.unconverged) return *error = "compression did not converge", false;
  *force = c.back().force;
  *area = cross_section(m);
  *nodes = m.num_nodes();
  return true;
}

// The apparent moduli F / (A strain) of spec compressed to `strain` between frictionless
// (e_app[0]) and bonded (e_app[1]) plates, over the lattice's rest cross-section.
bool apparent_moduli(const BodySpec& spec, double strain, double e_app[2], long* nodes,
                     std::string* error) {
  for (int bonded = 0; bonded < 2; ++bonded) {
    double f = 0, area = 0;
    if (!compress_force(spec, bonded, strain, &f, &area, nodes, error)) return false;
    e_app[bonded] = f / (area * strain);
  }
  return true;
}

// A rigid frictionless sphere of radius R (surface contact through its proxy) pressed into the
// middle of the top face to `depth` in `samples` increments, quasi-static: the indentation (the
// device's travel less the coupling's stretch, m) and the force (N) at each increment.
bool sphere_curve(BodySpec spec, double R, double depth, int samples, std::vector<double>* d,
                  std::vector<double>* force, long* nodes, std::string* error) {
  const io::BoundingBox box = io::bounding_box(spec.mesh);
  const Vec3 top(0.5 * (box.min.x() + box.max.x()), 0.5 * (box.min.y() + box.max.y()), box.max.z());
  ProbeSpec probe;
  probe.radius = R;
  probe.contact = ContactModel::kSurface;
  spec.probes = {probe};
  spec.options.integrator = Integrator::kImplicitEuler;
  Model m;
  if (std::string e = build_model(spec, &m); !e.empty()) return *error = e, false;
  const double kvc = coupling_stiffness(m, 0, R);
  QuasiStaticOptions o;
  o.samples = samples;
  o.tolerance = 1e-6;
  QuasiStaticStats st;
  const Curve c = quasi_static_curve(
      m, [&](const Model&, State& s, double u) { set_probe(s, 0, top + Vec3(0, 0, R - u)); },
      [](const Model&, const State& s, const Workspace&) { return s.probes[0].force.z(); }, depth,
      o, &st);
  if (st.unconverged) return *error = "sphere indentation did not converge", false;
  d->clear();
  force->clear();
  for (const auto& pt : c) {
    d->push_back(pt.displacement - pt.force / kvc);
    force->push_back(pt.force);
  }
  *nodes = m.num_nodes();
  return true;
}

}  // namespace

void register_validate(CLI::App& app, Runner* run) {
  struct Opts {
    std::string configs = "configs/validation", out_dir = "validation-out";
    bool quick = false;
    std::vector<std::string> cases = {"cylinder", "cube", "punch", "layer", "hertz"};
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "validate", "Small-strain standard cases against closed-form continuum results");
  cmd->add_option("--configs", o->configs, "folder of the validation scenes")
      ->capture_default_str();
  cmd->add_option("--out-dir", o->out_dir, "folder for the curves (CSV)")->capture_default_str();
  cmd->add_flag("--quick", o->quick,
                "the served resolutions only (no refinement study, no Hertz sphere)");
  cmd->add_option("--case", o->cases,
                  "cylinder, cube, punch, layer, hertz (repeatable; default: all)")
      ->check(CLI::IsMember({"cylinder", "cube", "punch", "layer", "hertz"}));
  cmd->callback([o, run] {
    *run = [o]() -> int {
      const char* me = "conica-lab validate";
      BodySpec cyl, cube, block;
      for (auto [name, spec] :
           {std::pair{"cylinder-ef30", &cyl}, {"cube-ef30", &cube}, {"punch-block-ef30", &block}})
        if (std::string e = io::load_scene(o->configs + "/" + name + ".pbtxt", spec); !e.empty()) {
          std::fprintf(stderr, "%s: %s\n", me, e.c_str());
          return 2;
        }
      std::error_code ec;
      std::filesystem::create_directories(o->out_dir, ec);
      const Moduli mo = moduli(cyl);
      std::printf(
          "EF30 card, isotropic estimate: E %.5g Pa, Poisson %.4f, K %.5g Pa, G %.5g Pa\n\n", mo.E,
          mo.nu, mo.K, mo.G);
      std::printf("| case | resolution | nodes | conica | reference | difference |\n");
      std::printf("|---|---|---|---|---|---|\n");
      std::string error;
      // Cylinders: uniaxial and bonded, at the served resolution and refined.
      const double R = 0.025, H = 0.03, strain = 0.002, S = R / (2 * H);
      auto wanted = [&](const char* c) {
        return std::find(o->cases.begin(), o->cases.end(), c) != o->cases.end();
      };
      std::vector<std::array<int, 2>> cyl_res = {{10, 6}};
      if (!o->quick) cyl_res = {{10, 6}, {14, 8}, {20, 12}};
      if (!wanted("cylinder")) cyl_res.clear();
      for (const auto& r : cyl_res) {
        BodySpec s = cyl;
        s.mesh = make_cylinder_lattice(R, H, r[0], r[1]);
        double e_app[2] = {0, 0};
        long n = 0;
        if (!apparent_moduli(s, strain, e_app, &n, &error)) {
          std::fprintf(stderr, "%s: cylinder: %s\n", me, error.c_str());
          return 1;
        }
        std::printf(
            "| frictionless cylinder 50 x 30 mm, strain %.3g: apparent modulus | %d x %d "
            "cells | %ld | %.5g Pa | %.5g Pa (E, isotropic estimate) | %+.2f %% |\n",
            strain, r[0], r[1], n, e_app[0], mo.E, 100 * (e_app[0] / mo.E - 1));
        std::printf(
            "| bonded / frictionless cylinder, same strain: modulus ratio | %d x %d cells "
            "| %ld | %.4f | %.4f (Gent-Lindley 1 + 2 S^2, S = 0.417, incompressible) | "
            "%+.2f %% |\n",
            r[0], r[1], n, e_app[1] / e_app[0], 1 + 2 * S * S,
            100 * (e_app[1] / e_app[0] / (1 + 2 * S * S) - 1));
      }
      // The bonded cube: shape factor a / (4 h) = 1/4, at the served 3 mm cells and refined (even
      // cell counts, so the scene's centre and edge pins stay on nodes).
      std::vector<int> cube_res = {10};
      if (!o->quick) cube_res = {10, 14, 20};
      if (!wanted("cube")) cube_res.clear();
      for (int c : cube_res) {
        const double side = 0.03, Sc = side / (4 * side);
        BodySpec s = cube;
        s.mesh = make_box_lattice(Vec3(side, side, side), {c, c, c});
        double e_app[2] = {0, 0};
        long n = 0;
        if (!apparent_moduli(s, strain, e_app, &n, &error)) {
          std::fprintf(stderr, "%s: cube: %s\n", me, error.c_str());
          return 1;
        }
        std::printf(
            "| bonded / frictionless cube 30 mm, strain %.3g: modulus ratio | %d x %d x %d cells "
            "| %ld | %.4f | %.4f (Gent-Lindley 1 + 2 S^2, S = 0.25, incompressible) | %+.2f %% |\n",
            strain, c, c, c, n, e_app[1] / e_app[0], 1 + 2 * Sc * Sc,
            100 * (e_app[1] / e_app[0] / (1 + 2 * Sc * Sc) - 1));
      }
      // Flat punch on the block: Sneddon force and the Boussinesq surface profile, for the disc
      // of the area the punch's faces cover (radius a_eq; it tends to a as the lattice refines).
      const double a = 0.005, d = 5e-5;
      const double Es = mo.E / (1 - mo.nu * mo.nu);
      std::vector<int> across = {24};
      if (!o->quick) across = {16, 24, 32};
      if (!wanted("punch")) across.clear();
      for (int c : across) {
        BodySpec s = block;
        s.mesh = make_box_lattice(Vec3(0.06, 0.06, 0.03), {c, c, c / 2});
        // The nodes within the radius, then whole faces (the profile from the latter, the rule
        // of `indent` and `fem-reference`).
        double f = 0, area = 0, ae = 0;
        long n = 0;
        std::vector<Vec3> rest, x;
        for (PunchRule rule : {PunchRule::kNodes, PunchRule::kFaces}) {
          PunchPress press;
          if (std::string e = press_flat_punch(s, a, d, rule, &press); !e.empty()) {
            std::fprintf(stderr, "%s: punch: %s\n", me, e.c_str());
            return 1;
          }
          f = press.force;
          area = press.area;
          n = static_cast<long>(press.rest.size());
          rest = std::move(press.rest);
          x = std::move(press.x);
          // Against the disc of the faces' area, or of the radius for the nodes (their rigid
          // faces are smaller, the ring of faces around them ramps down).
          ae = std::sqrt(area / M_PI);
          const bool nodes_rule = rule == PunchRule::kNodes;
          const double ref = 2 * (nodes_rule ? a : ae) * Es * d;
          char eq[48] = "";
          if (!nodes_rule) std::snprintf(eq, sizeof eq, ", a_eq = %.3g mm", ae * 1e3);
          std::printf(
              "| flat punch a = 5 mm, d = %.3g mm on the 60 x 60 x 30 mm block, %s: force | %d x "
              "%d x %d cells | %ld | %.5g N | %.5g N (Sneddon, half-space, 2 %s E* d%s) | %+.2f "
              "%% |\n",
              d * 1e3, nodes_rule ? "the nodes within a" : "the faces within a", c, c, c / 2, n, f,
              ref, nodes_rule ? "a" : "a_eq", eq, 100 * (f / ref - 1));
        }
        // Profile along +x through the centre of the top face.
        const std::string csv = o->out_dir + "/boussinesq-" + std::to_string(c) + ".csv";
        std::ofstream out(csv);
        out << "r_mm,w_over_d,boussinesq\n";
        double rms = 0;
        int m = 0;
        for (size_t i = 0; i < rest.size(); ++i) {
          const Vec3 p = rest[i] - Vec3(0.03, 0.03, 0.03);
          if (std::abs(p.z()) > 1e-9 || std::abs(p.y()) > 1e-9 || p.x() < -1e-9) continue;
          const double r = p.x(), w = (rest[i].z() - x[i].z()) / d;
          const double b = r <= ae + 1e-9 ? 1.0 : 2 / M_PI * std::asin(ae / r);
          out << r * 1e3 << "," << w << "," << b << "\n";
          if (r > ae + 1e-9 && r <= 0.025) {
            rms += (w - b) * (w - b);
            ++m;
          }
        }
        std::printf(
            "| Boussinesq surface profile w(r) / d, a_eq < r <= 25 mm: RMS difference | %d x "
            "%d x %d cells | %ld | %.4f | 0 (w / d = (2 / pi) asin(a_eq / r)) | (of d) |\n",
            c, c, c / 2, n, std::sqrt(rms / std::max(1, m)));
      }
      // Hayes: the punch (the nodes within a) on layers of the block's footprint, 30 to 5 mm thick
      // in whole cubic cells, bonded to the rigid base.
      std::vector<int> layer_across = {24};
      if (!o->quick) layer_across = {24, 32};
      if (!wanted("layer")) layer_across.clear();
      for (int c : layer_across) {
        const double cell = 0.06 / c;
        double f_thick = 0, kappa_thick = 0, h_thick = 0;
        for (double target : {0.03, 0.015, 0.01, 0.005}) {
          const int nz = std::max(1, static_cast<int>(std::lround(target / cell)));
          const double h = nz * cell;
          BodySpec s = block;
          s.mesh = make_box_lattice(Vec3(0.06, 0.06, h), {c, c, nz});
          PunchPress press;
          if (std::string e = press_flat_punch(s, a, d, PunchRule::kNodes, &press); !e.empty()) {
            std::fprintf(stderr, "%s: layer: %s\n", me, e.c_str());
            return 1;
          }
          const double f = press.force;
          const long n = static_cast<long>(press.rest.size());
          const double kappa = bonded_layer_kappa(a / h, mo.nu);
          const double ref = bonded_layer_punch_force(a, h, mo.E, mo.nu, d);
          std::printf(
              "| flat punch a = 5 mm, d = %.3g mm on a 60 x 60 x %.4g mm layer bonded to its base "
              "(a / h = %.3g), the nodes within a: force | %d x %d x %d cells | %ld | %.5g N | "
              "%.5g N (Hayes, 2 a E* d kappa, kappa = %.4f) | %+.2f %% |\n",
              d * 1e3, h * 1e3, a / h, c, c, nz, n, f, ref, kappa, 100 * (f / ref - 1));
          if (f_thick == 0) {
            f_thick = f;
            kappa_thick = kappa;
            h_thick = h;
            continue;
          }
          std::printf(
              "| the same over the %.4g mm layer's force: thickness correction | %d x %d x %d "
              "cells | %ld | %.4f | %.4f (Hayes' kappa ratio) | %+.2f %% |\n",
              h_thick * 1e3, c, c, nz, n, f / f_thick, kappa / kappa_thick,
              100 * (f / f_thick / (kappa / kappa_thick) - 1));
        }
      }
      // Hertz: a 10 mm sphere on the same block, to a tenth of its radius (contact radius up to
      // 3.2 mm against the 30 mm layer: a / h <= 0.11), F = (4 / 3) E* sqrt(R) d^1.5.
      if (!o->quick && wanted("hertz")) {
        const double Rs = 0.01, ds = 0.1 * Rs;
        for (int c : {16, 24, 32}) {
          BodySpec s = block;
          s.mesh = make_box_lattice(Vec3(0.06, 0.06, 0.03), {c, c, c / 2});
          std::vector<double> dd, ff;
          long n = 0;
          if (!sphere_curve(s, Rs, ds, 5, &dd, &ff, &n, &error)) {
            std::fprintf(stderr, "%s: sphere: %s\n", me, error.c_str());
            return 1;
          }
          const double hz = 4.0 / 3.0 * Es * std::sqrt(Rs) * std::pow(dd.back(), 1.5);
          double mean = 0;
          int k = 0;
          for (size_t i = 1; i < dd.size(); ++i) {
            if (!(dd[i] > 0.015 * Rs)) continue;
            mean += std::abs(ff[i] / (4.0 / 3.0 * Es * std::sqrt(Rs) * std::pow(dd[i], 1.5)) - 1);
            ++k;
          }
          std::printf(
              "| sphere R = 10 mm on the 60 x 60 x 30 mm block, d = %.3g mm: force (mean |error| "
              "over d = 0.2-1 mm: %.1f %%) | %d x %d x %d cells | %ld | %.5g N | %.5g N (Hertz, "
              "(4 / 3) E* sqrt(R) d^1.5) | %+.2f %% |\n",
              dd.back() * 1e3, 100 * mean / std::max(1, k), c, c, c / 2, n, ff.back(), hz,
              100 * (ff.back() / hz - 1));
        }
      }
      return 0;
    };
  });
}

}  // namespace conica::lab
