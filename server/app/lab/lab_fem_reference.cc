// conica-lab fem-reference: a scene's compression or indentation test as a CalculiX deck
// (lab/fem_reference.h), run with ccx when it is installed, its force curve read back and
// written as displacement_mm,force_N, so that a conica curve (compress, indent) can be checked
// against a continuum reference of the same geometry and boundary conditions.
//
// The hyperelastic law is fitted to the same uniaxial data as the scene's card: the measured
// curves given with --fit-data (stress over the specimen's rest cross-section, strain over its
// height, --fit-specimen-mm), else the card's own homogeneous uniaxial response (the lattice cell
// with the scene's element terms, lab/compression.h). Its bulk modulus gives the scene body's
// small-strain Poisson ratio unless --poisson says otherwise.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "app/lab/lab.h"
#include "io/curve_reader.h"
#include "io/mesh_repair.h"
#include "io/scene.h"
#include "lab/calibration.h"
#include "lab/compression.h"
#include "lab/fem_reference.h"

namespace conica::lab {

namespace {

bool read_text(const std::string& path, std::string* text) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream s;
  s << in.rdbuf();
  *text = s.str();
  return true;
}

// Linear interpolation of the reference at displacement u (m); NaN outside it.
double at(const std::vector<FemPoint>& c, double u) {
  for (size_t k = 1; k < c.size(); ++k)
    if (u <= c[k].displacement + 1e-12) {
      const double t = (u - c[k - 1].displacement) / (c[k].displacement - c[k - 1].displacement);
      return c[k - 1].force + t * (c[k].force - c[k - 1].force);
    }
  return std::nan("");
}

}  // namespace

void register_fem_reference(CLI::App& app, Runner* run) {
  struct Opts {
    std::string scene, test = "compress", out = "-", dir = "fem-reference", compare;
    std::vector<std::string> fit_data;
    std::vector<double> specimen_mm = {50, 30};
    double to_strain = 0.3, depth_mm = 0, radius_mm = 0, poisson = -2, fit_max_strain = 0.5;
    double fine_mm = -1;
    bool bonded = false, punch_bonded = false, full = false, no_run = false, c3d20 = false;
    int refine = 2, increments = 20;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* cmd = app.add_subcommand(
      "fem-reference",
      "Write a scene's compress or indent test as a CalculiX deck, run ccx, read its force curve");
  cmd->add_option("--scene", o->scene, "scene file (.pbtxt)")->required();
  cmd->add_option("--test", o->test, "compress or indent")->capture_default_str();
  cmd->add_flag("--bonded", o->bonded, "compress: both plates bonded; indent: the base clamped");
  cmd->add_option("--to-strain", o->to_strain, "compress: final plate travel over body height")
      ->capture_default_str();
  cmd->add_option("--punch-radius", o->radius_mm, "indent: punch radius, mm");
  cmd->add_option("--depth", o->depth_mm, "indent: final punch travel, mm");
  cmd->add_flag("--punch-bonded", o->punch_bonded, "indent: the punch holds its nodes in x, y");
  cmd->add_option("--refine", o->refine, "each scene hexahedron split into N^3 quadratic elements")
      ->capture_default_str();
  cmd->add_flag("--c3d20", o->c3d20,
                "fully integrated C3D20 elements (default: C3D20R for compress, C3D20 for indent)");
  cmd->add_option("--fine-mm", o->fine_mm,
                  "indent on a box lattice: the lattice kept within this distance of the punch "
                  "axis and of the top face, cells up to twice as wide per cell beyond "
                  "(default: twice the punch radius; 0: the whole lattice)");
  cmd->add_flag("--full", o->full, "model the whole body (default: a quarter when symmetric)");
  cmd->add_option("--increments", o->increments, "at least this many load increments")
      ->capture_default_str();
  cmd->add_option("--poisson", o->poisson,
                  "small-strain Poisson ratio of the law (default: the scene body's)");
  cmd->add_option("--fit-data", o->fit_data,
                  "measured compression curves to fit the law to (default: the card's own "
                  "homogeneous uniaxial curve)");
  cmd->add_option("--fit-specimen-mm", o->specimen_mm,
                  "diameter and height of the --fit-data cylinders, mm")
      ->expected(2)
      ->capture_default_str();
  cmd->add_option("--fit-max-strain", o->fit_max_strain, "fit up to this strain")
      ->capture_default_str();
  cmd->add_option("--dir", o->dir, "directory for the deck (job.inp) and ccx's files")
      ->capture_default_str();
  cmd->add_flag("--no-run", o->no_run, "write the deck only");
  cmd->add_option("--out", o->out, "CSV displacement_mm,force_N ('-': stdout)")
      ->capture_default_str();
  cmd->add_option("--compare", o->compare,
                  "a conica CSV (displacement_mm,force_N) to print against the reference");
  cmd->callback([o, run] {
    *run = [o]() -> int {
      const char* me = "conica-lab fem-reference";
      FemCase c;
      if (o->test == "compress") {
        c.test = FemCase::Test::kCompress;
        if (!(o->to_strain > 0 && o->to_strain < 1)) {
          std::fprintf(stderr, "%s: need 0 < --to-strain < 1\n", me);
          return 2;
        }
      } else if (o->test == "indent") {
        c.test = FemCase::Test::kIndent;
        if (!(o->radius_mm > 0) || !(o->depth_mm > 0)) {
          std::fprintf(stderr, "%s: indent needs --punch-radius > 0 and --depth > 0 (mm)\n", me);
          return 2;
        }
      } else {
        std::fprintf(stderr, "%s: --test must be compress or indent (got \"%s\")\n", me,
                     o->test.c_str());
        return 2;
      }
      if (o->refine < 1 || o->refine > 8 || o->increments < 1) {
        std::fprintf(stderr, "%s: need 1 <= --refine <= 8 and --increments >= 1\n", me);
        return 2;
      }
      BodySpec spec;
      if (std::string e = io::load_scene(o->scene, &spec); !e.empty()) {
        std::fprintf(stderr, "%s: %s\n", me, e.c_str());
        return 2;
      }
      if (spec.mesh.hexahedra.empty()) {
        std::fprintf(stderr,
                     "%s: %s: the body has no hexahedra (needs a lattice, a cylinder or "
                     "a hexahedral mesh)\n",
                     me, o->scene.c_str());
        return 2;
      }
      double zlo = spec.mesh.nodes[0].z(), zhi = zlo;
      for (const Vec3& x : spec.mesh.nodes) {
        zlo = std::min(zlo, x.z());
        zhi = std::max(zhi, x.z());
      }
      c.bonded = o->bonded;
      c.punch_bonded = o->punch_bonded;
      c.punch_radius = o->radius_mm * 1e-3;
      c.travel =
          c.test == FemCase::Test::kCompress ? o->to_strain * (zhi - zlo) : o->depth_mm * 1e-3;
      c.increments = o->increments;
      c.full_integration = o->c3d20 || c.test == FemCase::Test::kIndent;

      // The law, fitted to the same data as the card.
      const double nu = o->poisson > -1 ? o->poisson
                                        : body_poisson(lattice_moduli(spec.groups),
                                                       spec.bulk_modulus, spec.shear_modulus);
      std::vector<double> strain, stress;
      std::string source;
      if (!o->fit_data.empty()) {
        const double d = o->specimen_mm[0] * 1e-3, h = o->specimen_mm[1] * 1e-3;
        const double area = M_PI * d * d / 4;
        for (const std::string& f : o->fit_data) {
          io::CurveRequest rq;
          rq.height = h;
          auto r = io::read_curve(f, rq);
          if (!r) {
            std::fprintf(stderr, "%s: %s\n", me, r.error().c_str());
            return 2;
          }
          for (const auto& p : r.value().samples)
            if (p.displacement / h <= o->fit_max_strain) {
              strain.push_back(p.displacement / h);
              stress.push_back(p.force / area);
            }
        }
        source = std::to_string(o->fit_data.size()) + " measured curve(s)";
      } else {
        Model cell;
        if (std::string e =
                make_uniaxial_cell(spec.groups, spec.mapping, 0.01, &cell, spec.bulk_modulus,
                                   spec.shear_modulus, spec.shear_stiffening);
            !e.empty()) {
          std::fprintf(stderr, "%s: %s: %s\n", me, o->scene.c_str(), e.c_str());
          return 2;
        }
        for (int k = 1; k <= 50; ++k) strain.push_back(o->fit_max_strain * k / 50);
        stress = cell_stress_curve(cell, strain);
        source = "the card's homogeneous uniaxial curve";
      }
      YeohLaw law;
      if (std::string e = fit_yeoh(strain, stress, nu, 0.03, &law); !e.empty()) {
        std::fprintf(stderr, "%s: %s\n", me, e.c_str());
        return 2;
      }
      double err = 0;
      int n = 0;
      for (size_t k = 0; k < strain.size(); ++k)
        if (strain[k] >= 0.03) {
          err += std::abs(yeoh_uniaxial_stress(law, strain[k]) / stress[k] - 1);
          ++n;
        }
      std::fprintf(stderr,
                   "%s: Yeoh law fitted to %s up to strain %.3g: C10 %.6g Pa, C20 %.6g Pa, C30 "
                   "%.6g Pa, D1 %.6g 1/Pa (Poisson %.4g); mean relative error %.3g %%\n",
                   me, source.c_str(), o->fit_max_strain, law.c10, law.c20, law.c30, law.d1, nu,
                   100 * err / std::max(1, n));

      Mesh body = spec.mesh;
      std::string graded;
      const double fine = o->fine_mm >= 0 ? o->fine_mm * 1e-3 : 2 * c.punch_radius;
      if (c.test == FemCase::Test::kIndent && fine > 0) {
        const io::BoundingBox box = io::bounding_box(body);
        if (std::string e = coarsen_box_lattice(spec.mesh, 0.5 * (box.min + box.max), fine, &body);
            !e.empty()) {
          std::fprintf(stderr, "%s: %s: %s (--fine-mm 0 meshes the whole lattice)\n", me,
                       o->scene.c_str(), e.c_str());
          return 2;
        }
        char note[160];
        std::snprintf(note, sizeof note,
                      "; the lattice within %.3g mm of the punch, coarser beyond: %zu of %zu cells",
                      fine * 1e3, body.hexahedra.size(), spec.mesh.hexahedra.size());
        graded = note;
      }
      const FemMesh mesh = make_c3d20_mesh(body, o->refine, !o->full);
      std::string deck;
      int driven = 0;
      const std::string title =
          "conica-lab fem-reference: " + o->scene + ", " + o->test + (o->bonded ? " bonded" : "");
      if (std::string e = write_calculix_deck(mesh, law, c, title, &deck, &driven); !e.empty()) {
        std::fprintf(stderr, "%s: %s: %s\n", me, o->scene.c_str(), e.c_str());
        return 2;
      }
      std::error_code ec;
      std::filesystem::create_directories(o->dir, ec);
      const std::string inp = o->dir + "/job.inp";
      {
        std::ofstream f(inp);
        f << deck;
        if (!f) {
          std::fprintf(stderr, "%s: cannot write %s\n", me, inp.c_str());
          return 1;
        }
      }
      std::fprintf(stderr, "%s: wrote %s: %zu %s elements, %zu nodes (%s%s), %d driven nodes\n", me,
                   inp.c_str(), mesh.elements.size(), c.full_integration ? "C3D20" : "C3D20R",
                   mesh.nodes.size(),
                   mesh.quarter ? "a quarter, symmetry planes x and y" : "the whole body",
                   graded.c_str(), driven);
      if (o->no_run) return 0;
      if (std::system("command -v ccx >/dev/null 2>&1") != 0) {
        std::fprintf(stderr,
                     "%s: ccx (CalculiX, Debian package calculix-ccx) is not installed: deck "
                     "written, not run\n",
                     me);
        return 4;
      }
      const std::string cmdline = "cd '" + o->dir + "' && ccx -i job > job.log 2>&1";
      const int rc = std::system(cmdline.c_str());
      std::string dat;
      if (!read_text(o->dir + "/job.dat", &dat)) {
        std::fprintf(stderr, "%s: ccx wrote no %s/job.dat (exit %d, see job.log)\n", me,
                     o->dir.c_str(), rc);
        return 1;
      }
      std::vector<FemPoint> curve;
      if (std::string e = read_calculix_totals(dat, c, mesh.quarter, &curve); !e.empty()) {
        std::fprintf(stderr, "%s: %s/job.dat: %s\n", me, o->dir.c_str(), e.c_str());
        return 1;
      }
      const bool complete = curve.back().displacement >= c.travel * (1 - 1e-6);
      FILE* out = o->out == "-" ? stdout : std::fopen(o->out.c_str(), "w");
      if (!out) {
        std::fprintf(stderr, "%s: cannot write %s\n", me, o->out.c_str());
        return 1;
      }
      std::fputs("displacement_mm,force_N\n", out);
      for (const FemPoint& p : curve)
        std::fprintf(out, "%.6f,%.9g\n", p.displacement * 1e3, p.force);
      if (out != stdout) std::fclose(out);
      std::fprintf(stderr, "%s: ccx %s: %zu increments, force at %.4g mm: %.6g N\n", me,
                   complete ? "converged" : "STOPPED EARLY", curve.size() - 1,
                   curve.back().displacement * 1e3, curve.back().force);
      if (!o->compare.empty()) {
        std::string text;
        if (!read_text(o->compare, &text)) {
          std::fprintf(stderr, "%s: cannot read %s\n", me, o->compare.c_str());
          return 2;
        }
        std::istringstream in(text);
        std::string row;
        int line = 0;
        std::fprintf(stderr, "%s: displacement_mm  conica_N  reference_N  difference_%%\n", me);
        while (std::getline(in, row)) {
          ++line;
          if (line == 1) {
            if (row.rfind("displacement_mm,force_N", 0) != 0) {
              std::fprintf(stderr, "%s: %s:1: header must be displacement_mm,force_N\n", me,
                           o->compare.c_str());
              return 2;
            }
            continue;
          }
          double u_mm = 0, f_n = 0;
          if (std::sscanf(row.c_str(), "%lf,%lf", &u_mm, &f_n) != 2 || !std::isfinite(u_mm) ||
              !std::isfinite(f_n)) {
            std::fprintf(stderr, "%s: %s:%d: not two numbers\n", me, o->compare.c_str(), line);
            return 2;
          }
          const double f = at(curve, u_mm * 1e-3);
          if (!(u_mm > 0) || !std::isfinite(f)) continue;
          std::fprintf(stderr, "%s: %10.4f %12.6g %12.6g %8.2f\n", me, u_mm, f_n, f,
                       100 * (f_n / f - 1));
        }
      }
      return complete ? 0 : 3;
    };
  });
}

}  // namespace conica::lab
