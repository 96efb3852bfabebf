// conica-lab viscoelastic: the paper's Figure 9 on a scene whose springs carry a Maxwell branch.
// Three experiments with the scene's first plate (one is added on top when there is none):
//   relaxation  ramp to --strain in --ramp x tau, hold; force against time
//   creep       the plate load-controlled: ramp to the relaxation test's long-term force, hold;
//               travel against time
//   hysteresis  preload to half the strain, hold 5 tau, then 3 cycles of amplitude a quarter of
//               it at w tau = 1 (the largest loss of a standard linear solid): up to --strain,
//               and up to --loop-strain for a loop into the nonlinear law
// Writes PREFIX-relaxation.csv, -creep.csv, -hysteresis.csv, -summary.csv (and PNGs with
// --plot). Compares with the standard linear solid of the first group's card: relaxation time
// tau, retardation time tau (1 + k_m / K0), loop energy pi Ua^2 k_m,body w tau / (1 + (w tau)^2).
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>

#include "app/lab/lab.h"
#include "io/scene.h"
#include "lab/compression.h"
#include "lab/viscoelastic.h"

namespace conica::lab {

void register_viscoelastic(CLI::App& app, Runner* run) {
  struct Opts {
    std::string scene, out;
    double strain = 0.05, loop_strain = 0.2, ramp = 0.05, hold = 6;
    bool plot = false;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "viscoelastic", "Hysteresis, creep and force relaxation of a body with Maxwell branches");
  cmd->add_option("--scene", o->scene, "scene file (.pbtxt)")->required();
  cmd->add_option("--out", o->out, "output prefix")->required();
  cmd->add_option("--strain", o->strain, "strain of relaxation, creep and the linear loop")
      ->capture_default_str();
  cmd->add_option("--loop-strain", o->loop_strain, "strain of the second (large) loop")
      ->capture_default_str();
  cmd->add_option("--ramp", o->ramp, "ramp time of relaxation and creep, in units of tau")
      ->capture_default_str();
  cmd->add_option("--hold", o->hold, "hold time, in units of the analytic time constant")
      ->capture_default_str();
  cmd->add_flag("--plot", o->plot, "draw PREFIX-{relaxation,creep,hysteresis}.png");
  cmd->callback([o, run] {
    *run = [o]() -> int {
      BodySpec spec;
      if (std::string e = io::load_scene(o->scene, &spec); !e.empty()) {
        std::fprintf(stderr, "conica-lab viscoelastic: %s\n", e.c_str());
        return 2;
      }
      ensure_top_plate(&spec);
      Model m;
      if (std::string e = build_model(spec, &m); !e.empty()) {
        std::fprintf(stderr, "conica-lab viscoelastic: %s\n", e.c_str());
        return 2;
      }
      const SpringCard& card = m.groups.at(0).card;
      if (!(card.maxwell_k > 0)) {
        std::fprintf(stderr, "conica-lab viscoelastic: the first group has no Maxwell branch\n");
        return 2;
      }
      const double tau = card.maxwell_tau, q = card.maxwell_k / card.k0();
      const double tau_c = tau * (1 + q);
      const double H = plate_height(m), u0 = o->strain * H, tr = o->ramp * tau;
      auto ramp = [](double t, double tr, double v) { return t < tr ? v * t / tr : v; };

      // Relaxation.
      const PlateHistory rel = displacement_program(
          m, [&](double t) { return ramp(t, tr, u0); }, tr + o->hold * tau);
      const double tau_rel = decay_time(rel.time, rel.force, tr);
      double f_peak = 0;
      for (double f : rel.force) f_peak = std::max(f_peak, f);
      const double f_inf = rel.force.back(), k_e = f_inf / u0, k_m = q * k_e;
      // Analytic peak of a standard linear solid after a ramp of tr.
      const double f_peak_sls = k_e * u0 + k_m * u0 * (tau / tr) * (1 - std::exp(-tr / tau));

      // Creep at the long-term force of the relaxation test.
      const PlateHistory cr = force_program(
          m, [&](double t) { return ramp(t, tr, f_inf); }, tr + o->hold * tau_c);
      const double tau_cr = decay_time(cr.time, cr.displacement, tr);
      double u_first = 0;  // travel at the end of the load ramp
      for (size_t i = 0; i < cr.time.size(); ++i)
        if (cr.time[i] <= tr + 1e-12) u_first = cr.displacement[i];
      const double u_end = cr.displacement.back();
      // Analytic: u(t) = F/k_e - F (1/k_e - 1/(k_e + k_m)) exp(-t / tau_c) (instant loading).
      const double u_inf_sls = f_inf / k_e, u_inst_sls = f_inf / (k_e + k_m);
      const double u_end_sls =
          u_inf_sls - (u_inf_sls - u_inst_sls) * std::exp(-o->hold * tau_c / tau_c);

      // Hysteresis at w tau = 1: a preload of half the strain (ramp, hold 5 tau: the plate
      // cannot pull, so the force must stay compressive), then 3 cycles of amplitude a quarter
      // of the strain around it; the last cycle measured.
      const double w = 1 / tau, period = 2 * M_PI / w, t_cyc = tr + 5 * tau;
      auto loop = [&](double strain) {
        const double Ua = strain * H / 4;
        return displacement_program(
            m,
            [&, Ua](double t) {
              return t < t_cyc ? ramp(t, tr, 2 * Ua)
                               : 2 * Ua + Ua * (1 - std::cos(w * (t - t_cyc)));
            },
            t_cyc + 3 * period);
      };
      const PlateHistory hy = loop(o->strain), hy2 = loop(o->loop_strain);
      auto last_cycle = [&](const PlateHistory& h) {
        size_t b = 0;
        while (b < h.time.size() && h.time[b] < t_cyc + 2 * period - 1e-9) ++b;
        return loop_area(h.displacement, h.force, b, h.time.size());
      };
      auto from_cycles = [&](const PlateHistory& h) {  // drop the preload for the plot
        PlateHistory c;
        for (size_t i = 0; i < h.time.size(); ++i)
          if (h.time[i] >= t_cyc - 1e-9) {
            c.time.push_back(h.time[i]);
            c.displacement.push_back(h.displacement[i]);
            c.force.push_back(h.force[i]);
          }
        return c;
      };
      const double area = last_cycle(hy), area2 = last_cycle(hy2);
      const double Ua = u0 / 4;
      const double area_sls = M_PI * Ua * Ua * k_m * (w * tau) / (1 + (w * tau) * (w * tau));
      const PlateHistory hyc = from_cycles(hy), hy2c = from_cycles(hy2);

      // Files.
      auto write = [&](const std::string& path, const std::string& head,
                       const std::vector<std::vector<double>>& cols) {
        std::ofstream f(path);
        f << head << "\n";
        char buf[64];
        for (size_t i = 0; i < cols[0].size(); ++i) {
          for (size_t c = 0; c < cols.size(); ++c) {
            std::snprintf(buf, sizeof buf, "%s%.9g", c ? "," : "", cols[c][i]);
            f << buf;
          }
          f << "\n";
        }
        return static_cast<bool>(f);
      };
      std::vector<double> rel_sls(rel.time.size()), cr_sls(cr.time.size()), mm(cr.time.size());
      for (size_t i = 0; i < rel.time.size(); ++i) {
        const double t = rel.time[i];
        rel_sls[i] = t < tr ? k_e * u0 * t / tr + k_m * (u0 / tr) * tau * (1 - std::exp(-t / tau))
                            : k_e * u0 + (f_peak_sls - k_e * u0) * std::exp(-(t - tr) / tau);
      }
      for (size_t i = 0; i < cr.time.size(); ++i) {
        const double t = cr.time[i];
        cr_sls[i] =
            1e3 * (t < tr ? std::nan("")
                          : u_inf_sls - (u_inf_sls - u_inst_sls) * std::exp(-(t - tr) / tau_c));
        mm[i] = 1e3 * cr.displacement[i];
      }
      std::vector<double> hu(hyc.time.size()), hu2(hy2c.time.size()), nan2(hy2c.time.size(), NAN),
          nan1(hyc.time.size(), NAN);
      for (size_t i = 0; i < hu.size(); ++i) hu[i] = 1e3 * hyc.displacement[i];
      for (size_t i = 0; i < hu2.size(); ++i) hu2[i] = 1e3 * hy2c.displacement[i];
      // the two loops in one file: rows of the small loop, then of the large one
      std::vector<double> lu = hu, lf1 = hyc.force, lf2 = nan1, lt = hyc.time;
      lu.insert(lu.end(), hu2.begin(), hu2.end());
      lf1.insert(lf1.end(), nan2.begin(), nan2.end());
      lf2.insert(lf2.end(), hy2c.force.begin(), hy2c.force.end());
      lt.insert(lt.end(), hy2c.time.begin(), hy2c.time.end());
      const std::string P = o->out;
      bool ok =
          write(P + "-relaxation.csv", "time_s,force_N,sls_N", {rel.time, rel.force, rel_sls}) &&
          write(P + "-creep.csv", "time_s,displacement_mm,sls_mm,force_N",
                {cr.time, mm, cr_sls, cr.force}) &&
          write(P + "-hysteresis.csv", "displacement_mm,force_small_N,force_large_N,time_s",
                {lu, lf1, lf2, lt});
      char s[2048];
      std::snprintf(s, sizeof s,
                    "quantity,model,standard_linear_solid\n"
                    "relaxation time (s),%.6g,%.6g\n"
                    "relaxation peak force (N),%.6g,%.6g\n"
                    "relaxation long-term force (N),%.6g,%.6g\n"
                    "retardation time (s),%.6g,%.6g\n"
                    "creep travel at end of load ramp (mm; SLS: instantaneous),%.6g,%.6g\n"
                    "creep travel at end of hold (mm),%.6g,%.6g\n"
                    "loop energy at strain %g (mJ),%.6g,%.6g\n"
                    "loop energy at strain %g (mJ),%.6g,\n",
                    tau_rel, tau, f_peak, f_peak_sls, f_inf, k_e * u0, tau_cr, tau_c, 1e3 * u_first,
                    1e3 * u_inst_sls, 1e3 * u_end, 1e3 * u_end_sls, o->strain, 1e3 * area,
                    1e3 * area_sls, o->loop_strain, 1e3 * area2);
      std::ofstream(P + "-summary.csv") << s;
      std::printf("%s: height %.4g mm, k_m / K0 = %.4g, tau = %.4g s; body k_e = %.6g N/m\n%s",
                  o->scene.c_str(), H * 1e3, q, tau, k_e, s);
      if (!ok) {
        std::fprintf(stderr, "conica-lab viscoelastic: cannot write %s-*.csv\n", P.c_str());
        return 1;
      }
      if (o->plot) {
        int rc = run_plot_script(
            "plot_curves",
            "--out '" + P +
                "-relaxation.png' --title 'Force relaxation (hold at "
                "strain " +
                std::to_string(o->strain).substr(0, 4) +
                ")' --xlabel 'time (s)' --ylabel 'force (N)' --columns force_N,sls_N "
                "--labels 'model,standard linear solid' --styles 'b-,k:' '" +
                P + "-relaxation.csv'");
        rc |= run_plot_script("plot_curves",
                              "--out '" + P +
                                  "-creep.png' --title 'Creep under constant load' "
                                  "--xlabel 'time (s)' --ylabel 'plate travel (mm)' --columns "
                                  "displacement_mm,sls_mm --labels 'model,standard linear solid' "
                                  "--styles 'b-,k:' '" +
                                  P + "-creep.csv'");
        rc |= run_plot_script(
            "plot_curves", "--out '" + P +
                               "-hysteresis.png' --title 'Hysteresis, 3 cycles at "
                               "omega tau = 1' --xlabel 'plate travel (mm)' --ylabel 'force (N)' "
                               "--columns force_small_N,force_large_N --labels 'strain " +
                               std::to_string(o->strain).substr(0, 4) + ",strain " +
                               std::to_string(o->loop_strain).substr(0, 4) +
                               "' --styles 'b-,r-' '" + P + "-hysteresis.csv'");
        if (rc) return 1;
      }
      return 0;
    };
  });
}

}  // namespace conica::lab
