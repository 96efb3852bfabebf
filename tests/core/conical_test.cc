// Tests of the conical spring law against independent values: direct numerical integration of
// eq. (10), a long-double bisection inverse, finite differences, and the paper's figures.
#include "core/conical.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

namespace conica {
namespace {

// Paper's Figure 6 card family: n_a = 3, d = 1, G = 50, D1 = 2, D2 = 8, L0 = 90 n_a / n + Ls.
ConicalCard Fig6Card(double n) {
  ConicalCard c{50, 1, 2, 8, 0, 3};
  c.L0 = 90.0 * c.n_a / n + 0.0;  // Ls = 0 for this card (Type I/II boundary)
  return c;
}

ConicalCard Table2Card(double d) { return ConicalCard{50, d, 2, 8, 90, 3}; }

// Eq. (10) integrated numerically: each unit coil at radius r(n) deflects
// min(64 P r^3 / (G d^4), g) (it cannot close more than its gap). Composite Simpson over n with
// the kink located by the integrand itself, not by the law under test.
double DeflectionByQuadrature(const ConicalCard& c, double P) {
  const double r1 = c.D1 / 2, r2 = c.D2 / 2;
  const double nd = c.n_a * c.d;
  const double Ls = std::sqrt(std::max(0.0, nd * nd - (r2 - r1) * (r2 - r1)));
  const double g = (c.L0 - Ls) / c.n_a;
  auto f = [&](double n) {
    const double r = r1 + (r2 - r1) * n / c.n_a;
    return std::min(64.0 * P * r * r * r / (c.G * std::pow(c.d, 4)), g);
  };
  const int N = 400000;  // even
  const double h = c.n_a / N;
  long double sum = f(0) + f(c.n_a);
  for (int i = 1; i < N; ++i) sum += (i % 2 ? 4.0L : 2.0L) * f(i * h);
  return static_cast<double>(sum * h / 3.0L);
}

// Independent inverse: bisection in long double on the forward law delta(P).
double LoadByBisection(const ConicalLaw& law, double delta) {
  long double lo = 0, hi = law.solid_load();
  for (int i = 0; i < 200; ++i) {
    const long double mid = 0.5L * (lo + hi);
    if (law.deflection(static_cast<double>(mid)) < delta)
      lo = mid;
    else
      hi = mid;
  }
  return static_cast<double>(0.5L * (lo + hi));
}

TEST(ConicalCardTest, RejectsInvalidCardsNamingTheParameter) {
  ConicalCard ok{50, 1, 2, 8, 90, 3};
  EXPECT_EQ(validate(ok), "");
  auto with = [&](auto mutate) {
    ConicalCard c = ok;
    mutate(c);
    return validate(c);
  };
  EXPECT_NE(with([](ConicalCard& c) { c.d = 0; }).find("d must be > 0"), std::string::npos);
  EXPECT_NE(with([](ConicalCard& c) { c.d = -1; }).find("d must be > 0"), std::string::npos);
  EXPECT_NE(with([](ConicalCard& c) { c.D1 = 8; }).find("D1 must be < D2"), std::string::npos);
  EXPECT_NE(with([](ConicalCard& c) { c.D1 = 9; }).find("D1 must be < D2"), std::string::npos);
  EXPECT_NE(with([](ConicalCard& c) { c.n_a = 0; }).find("n_a must be > 0"), std::string::npos);
  EXPECT_NE(with([](ConicalCard& c) { c.G = NAN; }).find("G must be a finite"), std::string::npos);
  EXPECT_NE(with([](ConicalCard& c) { c.L0 = INFINITY; }).find("L0 must be a finite"),
            std::string::npos);
  // Table 2 white lattice (d = 1.5) is Type I with Ls = sqrt(4.5^2 - 3^2) = 3.354.
  EXPECT_NE(with([](ConicalCard& c) {
              c.d = 1.5;
              c.L0 = 3.3;
            }).find("L0 must be > solid height"),
            std::string::npos);
  EXPECT_NE(with([](ConicalCard& c) { c.G = 0; }).find("G must be > 0"), std::string::npos);
}

TEST(ConicalLawTest, TypeAndSolidHeightFollowEq3To5) {
  ConicalLaw red(Table2Card(0.5)), white(Table2Card(1.5));
  EXPECT_TRUE(red.telescopic());
  EXPECT_DOUBLE_EQ(red.solid_height(), 0.0);
  EXPECT_FALSE(white.telescopic());  // r2 - r1 = 3 < n_a d = 4.5
  EXPECT_NEAR(white.solid_height(), std::sqrt(4.5 * 4.5 - 9.0), 1e-12);
  EXPECT_NEAR(white.solid_height(), 3.354, 1e-3);
  // Table 2 stiffness by the linear-phase formula (the paper prints 0.00064 and 0.05149).
  EXPECT_NEAR(red.k0(), 7.66e-4, 0.005e-4);
  EXPECT_NEAR(white.k0(), 6.20e-2, 0.005e-2);
  // K0 is Wahl's eq. (2) integrated over the taper: compare with the cylindrical spring limit.
  ConicalCard near_cyl{50, 1, 4.0, 4.0 * (1 + 1e-7), 90, 3};
  const double r = 2.0;
  EXPECT_NEAR(ConicalLaw(near_cyl).k0() / (50.0 / (64.0 * r * r * r * 3)), 1.0, 1e-6);
}

TEST(ConicalLawTest, DeflectionMatchesDirectIntegrationOfEq10) {
  for (const ConicalCard& c : {Fig6Card(2), Fig6Card(3), Table2Card(0.5), Table2Card(1.5),
                               ConicalCard{80e3, 1e-3, 2e-3, 9e-3, 6e-3, 2.5}}) {
    ConicalLaw law(c);
    for (double frac : {0.1, 0.5, 0.99, 1.0, 1.5, 3.0, 10.0, 40.0}) {
      const double P = std::min(frac * law.transition_load(), 0.999 * law.solid_load());
      const double ref = DeflectionByQuadrature(c, P);
      EXPECT_NEAR(law.deflection(P), ref, 1e-8 * law.stroke()) << "P = " << P;
    }
  }
}

TEST(ConicalLawTest, Eq11MatchesRadiusFormWithUnbottomedCoils) {
  ConicalLaw law(Fig6Card(3));
  for (double frac : {1.5, 4.0, 20.0, 60.0}) {
    const double P = frac * law.transition_load();
    const double rt = std::cbrt(law.transition_load() * 64.0 / P);  // A / P with r2 = 4
    const double n = 3.0 * (rt - 1.0) / (4.0 - 1.0);  // unbottomed coils, eq. (6) inverted
    EXPECT_NEAR(law.deflection_eq11(P, n), law.deflection(P), 1e-9 * law.stroke());
  }
}

// The printed closed form eq. (12)-(19) does not invert eq. (11) in this copy of the paper:
// evaluated literally, it is far from the load that produces the deflection, or not real.
TEST(ConicalLawTest, PrintedEq12DoesNotInvertEq11) {
  ConicalLaw law(Fig6Card(3));
  int mismatches = 0, samples = 0;
  for (double frac : {0.5, 2.0, 8.0, 30.0}) {
    const double P = frac * law.transition_load();
    const double delta = law.deflection(P);
    const double printed = law.load_eq12_as_printed(delta);
    ++samples;
    if (!std::isfinite(printed) || std::abs(printed - P) > 0.01 * P) ++mismatches;
  }
  EXPECT_EQ(mismatches, samples);
}

TEST(ConicalLawTest, ExactInverseMatchesBisection) {
  for (const ConicalCard& c : {Fig6Card(3), Table2Card(0.5), Table2Card(1.5)}) {
    ConicalLaw law(c);
    for (int i = 0; i <= 400; ++i) {
      const double delta = law.stroke() * (i / 400.0) * 0.99999;
      const double ref = LoadByBisection(law, delta);
      EXPECT_NEAR(law.evaluate_exact(delta).force, ref,
                  1e-11 * std::max(ref, law.transition_load()))
          << "delta = " << delta;
    }
  }
}

TEST(ConicalLawTest, FastEvaluationWithinOneBillionthOfExactInverse) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double worst_f = 0, worst_k = 0;
  std::vector<ConicalCard> cards = {Fig6Card(0.5), Fig6Card(2), Fig6Card(3), Table2Card(0.5),
                                    Table2Card(1.5)};
  for (int i = 0; i < 40; ++i) {  // random valid cards across shapes
    ConicalCard c{1 + 1e4 * u(rng), 0.1 + u(rng), 0.5 + 2 * u(rng), 0, 0, 0.5 + 8 * u(rng)};
    c.D2 = c.D1 * (1.05 + 6 * u(rng));
    const double dr = 0.5 * (c.D2 - c.D1), nd = c.n_a * c.d;
    c.L0 = std::sqrt(std::max(0.0, nd * nd - dr * dr)) + 0.1 + 50 * u(rng);
    ASSERT_EQ(validate(c), "");
    cards.push_back(c);
  }
  for (double ratio : {0.001, 0.01, 0.99, 0.999}) {  // extreme tapers, both types
    for (double nd : {0.01, 100.0}) {
      ConicalCard c{1e5, nd / 3, ratio * 10, 10, 0, 3};
      const double dr = 0.5 * (c.D2 - c.D1);
      c.L0 = std::sqrt(std::max(0.0, nd * nd - dr * dr)) + 5;
      cards.push_back(c);
    }
  }
  // Both entry points: evaluate() and evaluate_batch() (the simulation's path).
  double worst_batch = 0;
  std::vector<double> delta(3000), f(3000), k(3000);
  for (const auto& c : cards) {
    for (double cap : {std::numeric_limits<double>::infinity(), 1e3}) {
      ConicalLaw law(c, cap * ConicalLaw(c).k0());
      const double hi = law.cap_deflection();
      for (int i = 0; i < 3000; ++i) {
        // Dense in the nonlinear phase, including its ends.
        const double t = (i < 2) ? i : u(rng);
        delta[i] = law.transition_deflection() + t * (hi - law.transition_deflection());
      }
      law.evaluate_batch(delta.data(), f.data(), k.data(), 3000);
      for (int i = 0; i < 3000; ++i) {
        const LawSample fast = law.evaluate(delta[i]), exact = law.evaluate_exact(delta[i]);
        worst_f = std::max(worst_f, std::abs(fast.force - exact.force) / exact.force);
        worst_batch = std::max(worst_batch, std::abs(f[i] - exact.force) / exact.force);
        if (std::isfinite(exact.stiffness) && exact.stiffness < 1e6 * law.k0()) {
          worst_k = std::max(worst_k, std::abs(fast.stiffness - exact.stiffness) / exact.stiffness);
          worst_batch = std::max(worst_batch, std::abs(k[i] - exact.stiffness) / exact.stiffness);
        }
      }
    }
  }
  EXPECT_LE(worst_f, 1e-9);
  EXPECT_LE(worst_k, 1e-9);
  EXPECT_LE(worst_batch, 1e-9);
  RecordProperty("worst_relative_error_force", std::to_string(worst_f));
  RecordProperty("worst_relative_error_stiffness", std::to_string(worst_k));
  std::printf("fast inverse, worst relative error: force %.3g, stiffness %.3g, batch %.3g\n",
              worst_f, worst_k, worst_batch);
}

// evaluate_batch() gives evaluate()'s values bit for bit in every phase, on both sides of every
// boundary, across chunk edges (n is not a multiple of the chunk) and in chunks that are entirely
// linear (the Hooke fast path) as well as mixed ones. No NaN anywhere.
TEST(ConicalLawTest, BatchMatchesScalarBitForBit) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<ConicalCard> cards = {Fig6Card(3), Fig6Card(0.5), Table2Card(1.5)};
  for (double ratio : {0.001, 0.999}) cards.push_back(ConicalCard{1e5, 0.01, ratio * 10, 10, 5, 3});
  for (const auto& c : cards) {
    for (double cap : {std::numeric_limits<double>::infinity(), 50.0, 0.5}) {
      const ConicalLaw law(c, cap * ConicalLaw(c).k0());  // cap 0.5 K0 <= K0: linear then cap
      const double dt = law.transition_deflection(), dc = law.cap_deflection(), S = law.stroke();
      std::vector<double> x;
      for (double b : {0.0, dt, dc, S}) {
        x.insert(x.end(), {b, std::nextafter(b, -1e300), std::nextafter(b, 1e300)});
      }
      for (int i = 0; i < 700; ++i) x.push_back(-dt + u(rng) * (1.2 * S + dt));  // mixed chunks
      for (int i = 0; i < 600; ++i) x.push_back((2 * u(rng) - 1) * dt);          // linear chunks
      for (int i = 0; i < 300; ++i) x.push_back(dt + u(rng) * (dc - dt));        // nonlinear
      const int n = static_cast<int>(x.size());
      ASSERT_NE(n % 256, 0);
      std::vector<double> f(n), k(n);
      law.evaluate_batch(x.data(), f.data(), k.data(), n);
      for (int i = 0; i < n; ++i) {
        const LawSample s = law.evaluate(x[i]);
        ASSERT_FALSE(std::isnan(f[i]) || std::isnan(k[i])) << "delta = " << x[i];
        ASSERT_EQ(f[i], s.force) << "delta = " << x[i] << ", i = " << i;
        ASSERT_EQ(k[i], s.stiffness) << "delta = " << x[i] << ", i = " << i;
      }
    }
  }
}

TEST(ConicalLawTest, StiffnessIsTheDerivativeOfForce) {
  for (double cap : {std::numeric_limits<double>::infinity(), 300.0}) {
    ConicalLaw law(Fig6Card(3), cap);
    for (int i = 1; i < 200; ++i) {
      const double delta = -20 + i * (law.stroke() + 30) / 200.0;
      if (std::isinf(cap) && delta > 0.999 * law.stroke()) continue;
      const double h = 1e-5;
      const double fd = (law.evaluate(delta + h).force - law.evaluate(delta - h).force) / (2 * h);
      const double k = law.evaluate(delta).stiffness;
      EXPECT_NEAR(k, fd, 1e-5 * std::max(k, 1.0)) << "delta = " << delta;
    }
  }
}

TEST(ConicalLawTest, ForceIsTheDerivativeOfEnergy) {
  for (double cap : {std::numeric_limits<double>::infinity(), 300.0}) {
    ConicalLaw law(Fig6Card(2), cap);
    for (int i = 1; i < 200; ++i) {
      const double delta = -20 + i * (law.stroke() + 30) / 200.0;
      if (std::isinf(cap) && delta > 0.999 * law.stroke()) continue;
      const double h = 1e-4;
      const double fd = (law.energy(delta + h) - law.energy(delta - h)) / (2 * h);
      const double f = law.evaluate(delta).force;
      EXPECT_NEAR(f, fd, 1e-6 * std::max(std::abs(f), 1e-3)) << "delta = " << delta;
    }
  }
}

TEST(ConicalLawTest, CompliancesAgreeWithStiffness) {
  ConicalLaw law(Table2Card(1.5));
  for (double frac : {0.5, 1.2, 5.0, 50.0}) {
    const double P = std::min(frac * law.transition_load(), 0.99 * law.solid_load());
    const double delta = law.deflection(P);
    EXPECT_NEAR(law.evaluate_exact(delta).stiffness * law.compliance(P), 1.0, 1e-9);
  }
}

// Pre-compression: the body's law is the plain law moved by delta0 along both axes.
ConicalCard Precompressed(ConicalCard c, double delta0) {
  c.precompression = delta0;
  return c;
}

TEST(ConicalPrecompressionTest, RejectsValuesOutsideTheStroke) {
  const ConicalCard c = Table2Card(1.5);  // Type I, Ls = 3.354, S = 86.65
  const double S = ConicalLaw(c).stroke();
  EXPECT_EQ(validate(Precompressed(c, 0.0)), "");
  EXPECT_EQ(validate(Precompressed(c, 0.999 * S)), "");
  for (double bad : {-1e-9, S, 2 * S}) {
    EXPECT_NE(validate(Precompressed(c, bad)).find("precompression must be >= 0 and < stroke"),
              std::string::npos)
        << bad;
  }
  EXPECT_NE(validate(Precompressed(c, NAN)).find("precompression must be a finite"),
            std::string::npos);
}

TEST(ConicalPrecompressionTest, ShiftedLawIsThePlainLawAtDelta0PlusDeltaMinusThePreload) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const ConicalCard& c : {Fig6Card(3), Table2Card(1.5)}) {
    for (double cap : {std::numeric_limits<double>::infinity(), 200.0}) {
      const ConicalLaw plain(c, cap * ConicalLaw(c).k0());
      const double S = plain.stroke(), dt = plain.transition_deflection();
      for (double delta0 : {0.5 * dt, dt, 0.5 * (dt + S), 0.9 * S}) {
        const ConicalLaw law(Precompressed(c, delta0), cap * ConicalLaw(c).k0());
        const double F0 = plain.evaluate(delta0).force;
        EXPECT_EQ(law.preload(), F0);
        EXPECT_EQ(law.evaluate(0.0).force, 0.0);  // at rest the body is in equilibrium
        EXPECT_EQ(law.rest_stiffness(), plain.evaluate_exact(delta0).stiffness);
        EXPECT_EQ(law.remaining_stroke(), S - delta0);
        std::vector<double> x = {-2 * delta0, -delta0, 0.0, dt - delta0, S - delta0};
        for (int i = 0; i < 400; ++i)
          x.push_back(-1.5 * delta0 + u(rng) * (1.1 * S + 0.5 * delta0));
        // Exact up to the rounding of the final subtraction (the compiler may fuse it with the
        // law's last multiplication): 1 ulp of the largest of operands and result.
        for (double d : x) {
          const LawSample a = law.evaluate(d), b = plain.evaluate(delta0 + d);
          const double ulp = std::numeric_limits<double>::epsilon() *
                             std::max({std::abs(b.force), F0, std::abs(b.force - F0)});
          ASSERT_NEAR(a.force, b.force - F0, ulp) << "delta0 " << delta0 << ", delta " << d;
          ASSERT_EQ(a.stiffness, b.stiffness) << "delta0 " << delta0 << ", delta " << d;
          ASSERT_EQ(a.phase, b.phase);
        }
        // Against an independent inverse (bisection on the forward law delta(P) of the plain
        // card), below the cap: force differences of the loads at delta0 + delta and delta0.
        for (double f : {-1.2, -0.5, 0.1, 0.5, 0.9}) {
          const double d = f * std::min(delta0, plain.cap_deflection() - delta0);
          if (delta0 + d <= 0 || delta0 + d >= plain.cap_deflection()) continue;
          const double ref = LoadByBisection(plain, delta0 + d) - LoadByBisection(plain, delta0);
          EXPECT_NEAR(law.evaluate_exact(d).force, ref, 1e-9 * plain.evaluate(delta0 + d).force)
              << "delta0 " << delta0 << ", delta " << d;
        }
        // Tension past -delta0: the spring itself is stretched, linear K0.
        const double far = -delta0 - 0.3 * dt;
        EXPECT_NEAR(law.evaluate(far).force, -F0 - plain.k0() * 0.3 * dt, 1e-12 * F0);
        EXPECT_EQ(law.evaluate(far).stiffness, plain.k0());
        EXPECT_EQ(law.evaluate(far).phase, Phase::kTension);
        // Forward law: deflection(P) is the body's deflection under P on top of the preload.
        if (delta0 + 0.3 * (S - delta0) < plain.cap_deflection()) {
          const double d = 0.3 * (S - delta0);
          EXPECT_NEAR(law.deflection(law.evaluate_exact(d).force), d, 1e-9 * S);
        }
      }
    }
  }
}

TEST(ConicalPrecompressionTest, BatchMatchesScalarBitForBit) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const ConicalCard& c : {Fig6Card(3), Table2Card(1.5)}) {
    const ConicalLaw plain(c);
    const double S = plain.stroke(), dt = plain.transition_deflection();
    for (double delta0 : {0.3 * dt, 0.5 * (dt + S)}) {
      const ConicalLaw law(Precompressed(c, delta0), 50 * plain.k0());
      std::vector<double> x;
      for (int i = 0; i < 700; ++i) x.push_back(-delta0 - dt + u(rng) * (1.2 * S + dt));
      for (int i = 0; i < 600; ++i) x.push_back(-delta0 + (2 * u(rng) - 1) * dt);  // linear
      const int n = static_cast<int>(x.size());
      std::vector<double> f(n), k(n);
      law.evaluate_batch(x.data(), f.data(), k.data(), n);
      // Stiffness bit for bit; force up to the rounding of the preload's subtraction (fused or
      // not with the law's last multiplication, the compiler's choice per loop): 1 ulp.
      for (int i = 0; i < n; ++i) {
        const LawSample s = law.evaluate(x[i]);
        const double ulp =
            std::numeric_limits<double>::epsilon() *
            std::max({std::abs(s.force + law.preload()), law.preload(), std::abs(s.force)});
        ASSERT_NEAR(f[i], s.force, ulp) << "delta = " << x[i];
        ASSERT_EQ(k[i], s.stiffness) << "delta = " << x[i];
      }
    }
  }
}

TEST(ConicalPrecompressionTest, StiffnessAndEnergyAreDerivatives) {
  const ConicalCard c = Fig6Card(3);
  const ConicalLaw plain(c);
  const double S = plain.stroke(), dt = plain.transition_deflection();
  for (double delta0 : {0.5 * dt, 0.5 * (dt + S)}) {
    const ConicalLaw law(Precompressed(c, delta0), 300 * plain.k0());
    EXPECT_EQ(law.energy(0.0), 0.0);
    for (int i = 1; i < 100; ++i) {
      const double d = -1.5 * delta0 + i * (S - 0.5 * delta0) / 100.0;
      const double h = 1e-5;
      const double fd = (law.evaluate(d + h).force - law.evaluate(d - h).force) / (2 * h);
      const double k = law.evaluate(d).stiffness;
      EXPECT_NEAR(k, fd, 1e-5 * std::max(k, 1.0)) << "delta0 " << delta0 << ", delta " << d;
      // Energy against Simpson's rule on the force from 0 to d (independent of energy()).
      const int N = 2000;
      double sum = law.evaluate_exact(0).force + law.evaluate_exact(d).force;
      for (int j = 1; j < N; ++j) sum += (j % 2 ? 4 : 2) * law.evaluate_exact(j * d / N).force;
      const double simpson = sum * d / N / 3;
      EXPECT_NEAR(law.energy(d), simpson, 1e-7 * std::max(std::abs(simpson), 1.0))
          << "delta0 " << delta0 << ", delta " << d;
    }
  }
  // In the nonlinear phase at rest the pre-compressed spring is stiffer than K0 from the start.
  const ConicalLaw pre(Precompressed(c, 0.5 * (dt + S)));
  EXPECT_GT(pre.rest_stiffness(), 1.5 * plain.k0());
  EXPECT_GT(pre.evaluate(0.1 * dt).stiffness, pre.rest_stiffness());
}

TEST(ConicalLawTest, PhaseBoundariesAndDegenerateInputs) {
  ConicalLaw law(Fig6Card(3));
  // 0 and 1e-12: linear, zero and tiny force, stiffness K0.
  EXPECT_EQ(law.evaluate(0).force, 0.0);
  EXPECT_EQ(law.evaluate(0).phase, Phase::kLinear);
  EXPECT_NEAR(law.evaluate(1e-12).force, law.k0() * 1e-12, 1e-30);
  EXPECT_EQ(law.evaluate(-1e-12).phase, Phase::kTension);
  EXPECT_DOUBLE_EQ(law.evaluate(-1.0).force, -law.k0());
  // Exactly at the transition: continuous force and stiffness from both sides.
  const double dt = law.transition_deflection();
  EXPECT_NEAR(dt, 0.332 * law.stroke(), 0.001 * law.stroke());  // docs/conical-law.md
  EXPECT_NEAR(law.evaluate(dt).force, law.transition_load(), 1e-12 * law.transition_load());
  const auto above = law.evaluate(std::nextafter(dt, 1e9));
  EXPECT_EQ(above.phase, Phase::kNonlinear);
  EXPECT_NEAR(above.force, law.transition_load(), 1e-9 * law.transition_load());
  EXPECT_NEAR(above.stiffness, law.k0(), 1e-6 * law.k0());
  // Exactly at solid height: finite force Ps, unbounded stiffness, no NaN.
  const auto solid = law.evaluate(law.stroke());
  EXPECT_NEAR(solid.force, law.solid_load(), 1e-9 * law.solid_load());
  EXPECT_FALSE(std::isnan(solid.stiffness));
  EXPECT_GT(solid.stiffness, 1e6 * law.k0());
  const auto past = law.evaluate(law.stroke() * 1.1);
  EXPECT_EQ(past.phase, Phase::kSolid);
  EXPECT_DOUBLE_EQ(past.force, law.solid_load());
  // With a cap, the law continues past solid height as a C1 line.
  ConicalLaw capped(Fig6Card(3), 100 * law.k0());
  const double dc = capped.cap_deflection();
  EXPECT_LT(dc, capped.stroke());
  EXPECT_NEAR(capped.evaluate(dc).stiffness, 100 * law.k0(), 1e-6 * 100 * law.k0());
  EXPECT_NEAR(capped.evaluate(std::nextafter(dc, 1e9)).force, capped.evaluate(dc).force,
              1e-9 * capped.evaluate(dc).force);
  EXPECT_TRUE(std::isfinite(capped.evaluate(10 * capped.stroke()).force));
}

// Figure 6: over the same displacement range (0..90), more coils in range -> more nonlinear.
// n = 0.5 and 1 stay linear; n = 2 turns at 45 and n = 3 at 30.
TEST(ConicalLawTest, Figure6MoreCoilsInRangeIsMoreNonlinear) {
  double last_ratio = 0;
  for (double n : {0.5, 1.0, 2.0, 3.0}) {
    ConicalLaw law(Fig6Card(n));
    const double k_end = law.evaluate(89.0).stiffness;
    const double ratio = k_end / law.k0();  // end stiffness over initial stiffness
    EXPECT_GE(ratio, last_ratio);
    last_ratio = ratio;
    if (n <= 1.0) {
      EXPECT_DOUBLE_EQ(ratio, 1.0);
    }
  }
  EXPECT_GT(last_ratio, 5.0);
  EXPECT_NEAR(ConicalLaw(Fig6Card(2)).transition_deflection(), 45, 0.5);
  EXPECT_NEAR(ConicalLaw(Fig6Card(3)).transition_deflection(), 30, 0.2);
}

// Figure 7: larger G -> smaller deflection at equal load, same shape (deflection scales 1/G).
TEST(ConicalLawTest, Figure7LargerShearModulusSameShape) {
  ConicalCard a = Fig6Card(3), b = a;
  b.G = 4 * a.G;
  ConicalLaw la(a), lb(b);
  for (double P : {0.001, 0.01, 0.1}) {
    EXPECT_LT(lb.deflection(P), la.deflection(P));
    EXPECT_NEAR(lb.deflection(4 * P), la.deflection(P), 1e-9 * la.stroke());
  }
}

}  // namespace
}  // namespace conica
