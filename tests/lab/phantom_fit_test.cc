// The calibration through the full body, on data no one here wrote: the Ecoflex 00-30
// phantom tests (shared/data/phantoms, Dawood et al.), fitted with configs/phantom-cylinder.pbtxt
// (first without its shear term: volume stiffness, Poisson ratio 0.49). The pair-spring body of
// the same scene buckled before 50 % strain and ended at 41-44 % (docs/paper-reproduction.md);
// with volume stiffness the full body stays load-bearing and follows the mean curve. A reduced
// budget (3 x 3 full-body grid of plain laws, no refinement) keeps the test near a minute; the
// command's default budget is in the docs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>

#include "core/stability.h"
#include "io/scene.h"
#include "lab/calibration.h"
#include "lab/compression.h"
#include "lab/quasi_static.h"
#include "phantom_curves.h"

namespace conica::lab {
namespace {

// The ten Ecoflex 00-30 tests (EF30_0T_A1..A5, B1..B5) of shared/data/phantoms.
void ReadEcoflex30(std::vector<Curve>* curves) {
  for (char series : {'A', 'B'})
    for (int i = 1; i <= 5; ++i) {
      curves->push_back(
          ReadPhantom("EF30_0T/EF30_0T_" + std::string(1, series) + std::to_string(i) + ".csv"));
      ASSERT_FALSE(curves->back().empty());
    }
}

// Mean relative error of a model curve (points 1..n of `c`, the first at rest left out) against
// the mean of the measured curves at the same travels, from point `first` of those on.
double ErrorAgainstMean(const Curve& c, const std::vector<Curve>& curves, int first,
                        std::vector<double>* grid_out = nullptr) {
  const size_t n = c.size() - 1;
  std::vector<double> grid(n), model(n), data;
  for (size_t k = 0; k < n; ++k) {
    grid[k] = c[k + 1].displacement;
    model[k] = c[k + 1].force;
  }
  std::string err;
  EXPECT_TRUE(mean_curve(curves, grid, &data, &err)) << err;
  if (grid_out) *grid_out = grid;
  return data.size() == n ? average_relative_error(model, data, first)
                          : std::numeric_limits<double>::infinity();
}

TEST(CalibrationFullBodyTest, VolumeStiffPhantomFollowsEcoflexToHalfItsHeight) {
  BodySpec spec;
  ASSERT_EQ(io::load_scene(CONICA_SOURCE_DIR "/configs/phantom-cylinder.pbtxt", &spec), "");
  ensure_top_plate(&spec);
  ASSERT_GT(spec.bulk_modulus, 0);
  spec.shear_modulus = 0;  // volume and spread stiffness only, Poisson 0.49
  spec.bulk_modulus = spec.spread_modulus = bulk_for_poisson(lattice_moduli(spec.groups), 0.49);
  std::vector<Curve> curves;
  ASSERT_NO_FATAL_FAILURE(ReadEcoflex30(&curves));
  FitOptions o;
  o.max_strain = 0.5;
  o.full_grid = 3;
  o.full_grid_pre = 1;
  o.full_grid_poisson = 1;  // the scene's Poisson ratio only
  o.full_iterations = 0;
  o.column_floor = false;
  // Without shear stiffness this body's layers end uneven at every card of this grid (the fit's
  // layer check would reject them all; docs/paper-reproduction.md): here only its load-bearing
  // curve is checked.
  o.max_layer_spread = std::numeric_limits<double>::infinity();
  const FitResult r = calibrate(spec, curves, o);
  ASSERT_EQ(r.error, "");
  EXPECT_NEAR(r.poisson, 0.49, 1e-6);
  ASSERT_EQ(r.full.size(), r.data.size());
  std::printf("EF30_0T, full body with volume stiffness: average relative error %.3f %%\n",
              100 * r.full_error);
  // 2.1 % on this machine with this budget; the fit's objective is not smooth (the body can leave
  // its homogeneous state for a moment), so the bound leaves room for other floating-point paths.
  EXPECT_LT(r.full_error, 0.04) << "full body, average relative error to 50 % strain";
  // Load-bearing all the way: no grid step loses more than 3 % of the force (the pair-spring
  // body lost nearly all of it), and the last point carries the most.
  for (size_t k = 1; k < r.full.size(); ++k) EXPECT_GT(r.full[k], 0.97 * r.full[k - 1]) << k;
  EXPECT_EQ(*std::max_element(r.full.begin(), r.full.end()), r.full.back());
}

// Largest minus smallest outer radius (m) over the node layers of a compressed cylinder (nodes
// grouped by rest height).
double LayerRadiusSpread(const Model& m, const std::vector<Vec3>& x) {
  std::map<long, double> outer;
  for (int i = 0; i < m.num_nodes(); ++i) {
    double& r = outer[std::lround(m.rest[i].z() * 1e6)];
    r = std::max(r, std::hypot(x[i].x(), x[i].y()));
  }
  double lo = 1e9, hi = 0;
  for (const auto& [z, r] : outer) {
    std::printf("  layer at rest z %.1f mm: outer radius %.2f mm\n", z * 1e-3, r * 1e3);
    lo = std::min(lo, r);
    hi = std::max(hi, r);
  }
  return hi - lo;
}

TEST(CalibrationFullBodyTest, SpreadTermEvensTheLayersOfTheCompressedCylinder) {
  // configs/phantom-cylinder.pbtxt without and with its spread term, each at the card fitted to
  // EF30_0T with it (docs/figures/repro-fitvol-nospread-EF30_0T.card, repro-fitvol-EF30_0T.card),
  // compressed to 50 %: the outer radius of every node layer. A homogeneous incompressible
  // cylinder would have 25 mm / sqrt(0.5) = 35.4 mm everywhere. Third: the first card with the
  // spread term and shear stiffness as large as the springs' own (Poisson 0.49 kept): at that
  // card the spread term alone lets the body lean sideways (docs/paper-reproduction.md).
  BodySpec spec;
  ASSERT_EQ(io::load_scene(CONICA_SOURCE_DIR "/configs/phantom-cylinder.pbtxt", &spec), "");
  ensure_top_plate(&spec);
  struct Fitted {
    ConicalCard card;
    double bulk, spread;
    bool shear;
  };
  const ConicalCard nospread_card{4.33763314e12, 0.000301349474, 0.00667005279, 0.008, 0.01, 3,
                                  0.00285837853};
  const Fitted fits[] = {
      {nospread_card, 1198725.49, 0, false},
      {{2.96966327e10, 0.00104463246, 0.00666993017, 0.008, 0.01, 3, 0.000612511759},
       1185104.42,
       1185104.42,
       false},
      {nospread_card, 0, 0, true},
  };
  double spread_of[3];
  for (int k = 0; k < 3; ++k) {
    spec.groups[0].card.conical = fits[k].card;
    spec.bulk_modulus = fits[k].bulk;
    spec.spread_modulus = fits[k].spread;
    spec.shear_modulus = 0;
    if (fits[k].shear) {
      const LatticeModuli lm = lattice_moduli(spec.groups);
      spec.shear_modulus = lattice_shear(lm);
      spec.bulk_modulus = spec.spread_modulus = bulk_for_poisson(lm, 0.49, spec.shear_modulus);
    }
    Model m;
    ASSERT_EQ(build_model(spec, &m), "");
    CompressionStats st;
    compression_curve(m, 500e-3 / 60, 0.5, 10, &st);
    std::printf("%s:\n", k == 0   ? "without the spread term, its card"
                         : k == 1 ? "with the spread term, its card"
                                  : "with the spread and shear terms, the first card");
    spread_of[k] = LayerRadiusSpread(m, st.positions);
  }
  EXPECT_GT(spread_of[0], 2e-3) << "layers alternate without the spread term";
  EXPECT_LT(spread_of[1], 0.5e-3) << "even layers with it";
  EXPECT_LT(spread_of[2], 0.5e-3) << "even layers with shear stiffness";
}

// The Poisson ratio through the full body: a curve compressed by the shear-stiff phantom
// (configs/phantom-cylinder.pbtxt) at Poisson 0.46 with a card on the full-body grid is
// fitted with a grid over Poisson ratios 0.49 (the scene's), 0.46 and 0.43; the fit must come
// back to 0.46 and the curve itself. A force curve fixes the Poisson ratio only through the
// geometric stiffening (calibration.h); the same fit held at the scene's 0.49 must miss.
TEST(CalibrationFullBodyTest, PoissonGridRecoversTheRatioOfACurveTheBodyMade) {
  BodySpec spec;
  ASSERT_EQ(io::load_scene(CONICA_SOURCE_DIR "/configs/phantom-cylinder.pbtxt", &spec), "");
  ensure_top_plate(&spec);
  FitOptions o;
  o.max_strain = 0.3;
  o.points = 20;
  o.full_grid = 2;
  o.full_grid_pre = 1;
  o.full_grid_poisson = 3;
  o.poisson_min = 0.43;
  o.full_iterations = 0;
  o.column_floor = false;
  const LatticeModuli scene = lattice_moduli(spec.groups);
  const double scene_nu = body_poisson(scene, spec.bulk_modulus, spec.shear_modulus);
  ASSERT_NEAR(scene_nu, 0.49, 1e-3);
  const double want_nu = scene_nu - (scene_nu - o.poisson_min) / 2;
  // The grid's second taper and stroke (g = 2): bounds' midpoints of the upper halves; the
  // stroke's lower bound is 1.02 x the largest strain (edges carry the body's strain).
  const ShapeBounds& b = o.bounds;
  const double smin = std::max(b.stroke_min, 1.02 * o.max_strain);
  const CardShape want{1.5e5, b.taper_min + (b.taper_max - b.taper_min) * 0.75,
                       smin + (b.stroke_max - smin) * 0.75, 0};
  BodySpec truth = spec;
  truth.groups[0].card.conical = card_with_shape(spec.groups[0].card.conical, want);
  ASSERT_EQ(validate(truth.groups[0].card.conical), "");
  const LatticeModuli lm = lattice_moduli(truth.groups);
  truth.shear_modulus = spec.shear_modulus / lattice_shear(scene) * lattice_shear(lm);
  truth.bulk_modulus = bulk_for_poisson(lm, want_nu, truth.shear_modulus);
  truth.spread_modulus = truth.bulk_modulus * spec.spread_modulus / spec.bulk_modulus;
  Model m;
  ASSERT_EQ(build_model(truth, &m), "");
  const Curve measured = compression_curve(m, o.rate, o.max_strain, o.points);
  const FitResult r = calibrate(spec, {measured}, o);
  ASSERT_EQ(r.error, "");
  std::printf(
      "curve made at Poisson %.4f: fitted Poisson %.4f, taper %.4f, stroke %.4f, "
      "E_c %.6g Pa (made %.6g), full-body error %.3g %%\n",
      want_nu, r.poisson, r.shape.taper, r.shape.stroke, r.shape.modulus, want.modulus,
      100 * r.full_error);
  EXPECT_NEAR(r.poisson, want_nu, 1e-6);
  EXPECT_NEAR(r.shape.modulus / want.modulus, 1, 1e-3);
  EXPECT_LT(r.full_error, 1e-4);
  o.full_grid_poisson = 1;
  const FitResult held = calibrate(spec, {measured}, o);
  ASSERT_EQ(held.error, "");
  std::printf("held at the scene's Poisson %.4f: full-body error %.3g %%\n", held.poisson,
              100 * held.full_error);
  EXPECT_NEAR(held.poisson, scene_nu, 1e-9);
  EXPECT_GT(held.full_error, 10 * r.full_error);
}

// The card fitted to EF30_0T by the command (configs/phantom-cylinder.pbtxt: shear
// stiffness, its Poisson ratio through the full-body grid, which picked 0.45;
// docs/figures/repro-fitvol-EF30_0T.card), compressed again: within the 2 % of the
// measured mean curve to 50 % strain, and a homogeneous body (see the bounds below).
TEST(CalibrationFullBodyTest, ShearStiffPhantomFollowsEcoflexWithinTwoPercentWithEvenLayers) {
  BodySpec spec;
  ASSERT_EQ(io::load_scene(CONICA_SOURCE_DIR "/configs/phantom-cylinder.pbtxt", &spec), "");
  ensure_top_plate(&spec);
  spec.groups[0].card.conical = {4.76372418e+09, 0.00144625498, 0.00667, 0.008, 0.01, 3, 6.125e-10};
  spec.bulk_modulus = spec.spread_modulus = 257054.764;
  spec.shear_modulus = 14550.2892;
  EXPECT_NEAR(body_poisson(lattice_moduli(spec.groups), spec.bulk_modulus, spec.shear_modulus),
              0.45, 1e-3);
  std::vector<Curve> curves;
  ASSERT_NO_FATAL_FAILURE(ReadEcoflex30(&curves));
  Model m;
  ASSERT_EQ(build_model(spec, &m), "");
  CompressionStats st;
  const int n = 50;
  const Curve c = compression_curve(m, 500e-3 / 60, 0.5, n, &st);
  ASSERT_EQ(static_cast<int>(c.size()), n + 1);
  const int first = 2;  // 0.9 mm of 30: strain 0.03, the calibration's default skip
  std::vector<double> grid;
  const double e = ErrorAgainstMean(c, curves, first, &grid);
  ASSERT_NEAR(grid[first], 0.9e-3, 1e-9);
  std::printf("EF30_0T, shear-stiff full body at its fitted card: average relative error %.3f %%\n",
              100 * e);
  EXPECT_LT(e, 0.02);
  // This card is past its quasi-static buckling onset at 50 % (42-44 % on the square prism,
  // docs/materials.md), so how far its layers have swayed apart at the end of the travel depends
  // on the perturbation that seeds the sway: a last-bit change in the shear term's implicit
  // coefficient alone gave 0.92 mm, the element terms' forces summed in another order 1.11 mm
  // (0.50 mm before either). The homogeneous state is asserted where it is stable: compressed
  // to 40 % strain, within the fit's bound (layers measured about the rest centroid's axis) and,
  // about the cylinder's own axis, every layer within 0.6 mm of the others. The library's cards
  // (next test) are checked for the onset instead.
  std::printf("at 50 %% strain: layers %.2f mm apart (past the onset: not asserted)\n",
              1e3 * LayerRadiusSpread(m, st.positions));
  CompressionStats st40;
  compression_curve(m, 500e-3 / 60, 0.4, 40, &st40);
  std::printf("at 40 %% strain: layers %.2f mm apart\n",
              1e3 * LayerRadiusSpread(m, st40.positions));
  EXPECT_LE(st40.layer_spread, FitOptions{}.max_layer_spread * st40.half_width);
  EXPECT_LT(LayerRadiusSpread(m, st40.positions), 0.6e-3) << "even layers";
}

// The library's EF30_0T card (configs/materials, written by `conica-lab library`, its shear term
// raised where the material would lose strong ellipticity before 51 % strain) in the served
// phantom scene: the material check finds no onset to 50 %, and the full 847-node body, solved
// quasi-statically between frictionless plates, reaches half its height evenly and follows the
// ten Ecoflex 00-30 tests within 2 % (mean relative error from 4 % strain; 1.45 % here). The
// earlier card, fitted without the check, lost strong ellipticity at 45.4 % strain and its body
// found no equilibrium at 48 %.
TEST(CalibrationFullBodyTest, LibraryCardCompressesThePhantomEvenlyToHalfItsHeight) {
  BodySpec spec;
  ASSERT_EQ(io::load_scene(CONICA_SOURCE_DIR "/configs/phantom-ef30.pbtxt", &spec), "");
  ensure_top_plate(&spec);
  Model m;
  ASSERT_EQ(build_model(spec, &m), "");
  EXPECT_LT(uniaxial_compression_stability(m, Vec3::UnitZ(), 0.5).onset_strain, 0);
  std::vector<Curve> curves;
  ASSERT_NO_FATAL_FAILURE(ReadEcoflex30(&curves));
  m.planes[0].stiffness = std::max(m.planes[0].stiffness, rigid_plate_stiffness(m, false));
  const double H = plate_height(m);
  const int n = 25;
  QuasiStaticOptions qo;
  qo.samples = n;
  QuasiStaticStats st;
  const Curve c = quasi_static_curve(m, plate_load(m), plate_reaction(), 0.5 * H, qo, &st);
  EXPECT_LT(st.failed_at, 0);
  EXPECT_EQ(st.unconverged, 0);
  const int first = 1;  // 1.2 mm of 30: strain 0.04, the first point past the 3 % skip
  const double e = ErrorAgainstMean(c, curves, first);
  std::printf(
      "EF30_0T library card, full body quasi-static to 50 %%: average relative error "
      "%.3f %%, %ld steps, layer spread %.3g mm\n",
      100 * e, st.steps, 1e3 * layer_spread(m, st.positions));
  EXPECT_LT(e, 0.02);
  EXPECT_LE(layer_spread(m, st.positions), FitOptions{}.max_layer_spread * 0.025);
}

// Every card of configs/materials says what its recipe's body does: the fit scene
// (configs/phantom-cylinder.pbtxt) naming the card as its material, compressed quasi-statically
// in 25 increments as the library's body check does, gives the card's "# error:" to its printed
// digits against the mean of the recipe's tests (read here, not by the library); a card at or
// below 2 % reaches 50 % strain with every increment in equilibrium and no spring at its solid
// height; every card is strongly
// elliptic under uniaxial compression past 50 % (the fit keeps it to 51 %).
TEST(CalibrationFullBodyTest, EveryLibraryCardsErrorIsItsBodysThroughTheFitScene) {
  std::ifstream in(CONICA_SOURCE_DIR "/configs/phantom-cylinder.pbtxt");
  std::stringstream ss;
  ss << in.rdbuf();
  std::string base;
  {  // the scene without its group and element terms
    std::istringstream lines(ss.str());
    std::string line;
    int depth = 0;
    while (std::getline(lines, line)) {
      if (depth == 0 &&
          (line.rfind("bulk_modulus", 0) == 0 || line.rfind("spread_modulus", 0) == 0 ||
           line.rfind("shear_modulus", 0) == 0))
        continue;
      if (depth == 0 && line.rfind("group {", 0) == 0)
        depth = 1;
      else if (depth > 0) {
        depth += static_cast<int>(std::count(line.begin(), line.end(), '{')) -
                 static_cast<int>(std::count(line.begin(), line.end(), '}'));
      } else {
        base += line + "\n";
      }
    }
  }
  int cards = 0;
  for (const char* recipe : {"EF10_0T", "EF10_100T", "EF10_25T", "EF10_75T", "EF30_0T",
                             "EF30_12_5T", "EF30_50T", "EF50_12_5T", "EF50_50T"}) {
    SCOPED_TRACE(recipe);
    std::ifstream card(std::string(CONICA_SOURCE_DIR "/configs/materials/") + recipe + ".card");
    ASSERT_TRUE(card.good());
    double stated = -1;
    for (std::string line; std::getline(card, line);)
      if (line.rfind("# error: ", 0) == 0 && line.find("(full body)") != std::string::npos)
        stated = std::stod(line.substr(9));
    ASSERT_GT(stated, 0) << "no full-body error in the card";
    auto scene = io::parse_scene(base + "material: \"" + recipe + "\"\n", "library-card",
                                 CONICA_SOURCE_DIR "/configs");
    ASSERT_TRUE(scene) << scene.error();
    BodySpec spec = scene.value().spec;
    ensure_top_plate(&spec);
    Model m;
    ASSERT_EQ(build_model(spec, &m), "");
    EXPECT_LT(uniaxial_compression_stability(m, Vec3::UnitZ(), 0.505).onset_strain, 0);
    std::vector<Curve> curves;
    for (char series : {'A', 'B'})
      for (int i = 1; i <= 5; ++i)
        curves.push_back(ReadPhantom(std::string(recipe) + "/" + recipe + "_" + series +
                                     std::to_string(i) + ".csv"));
    m.planes[0].stiffness = std::max(m.planes[0].stiffness, rigid_plate_stiffness(m, false));
    QuasiStaticOptions qo;
    qo.samples = 25;
    qo.stop_at_failure = true;
    QuasiStaticStats st;
    const Curve c =
        quasi_static_curve(m, plate_load(m), plate_reaction(), 0.5 * plate_height(m), qo, &st);
    ASSERT_EQ(c.size(), 26u);
    const double e = ErrorAgainstMean(c, curves, 1);
    std::printf("%s: card %.4g %%, body %.4g %% (%zu groups, %ld steps, %d unsettled)\n", recipe,
                stated, 100 * e, spec.groups.size(), st.steps, st.unconverged);
    EXPECT_NEAR(100 * e, stated, 5e-4 * stated + 1e-9);
    if (stated <= 2) {
      EXPECT_LT(st.failed_at, 0);
      EXPECT_EQ(st.unconverged, 0);
      EXPECT_EQ(st.hard_stops, 0u);
    }
    ++cards;
  }
  EXPECT_EQ(cards, 9);
}

}  // namespace
}  // namespace conica::lab
