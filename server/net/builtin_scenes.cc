#include "net/builtin_scenes.h"

#include <cmath>

namespace conica::net {
namespace {

SpringCard tissue_card() {
  SpringCard c;
  c.law = LawKind::kConical;
  // G in Pa, lengths in m: K0 = G d^4 (r2 - r1) / (16 n_a (r2^4 - r1^4)) ~ 490 N/m.
  c.conical = ConicalCard{2e9, 1e-3, 2e-3, 8e-3, 10e-3, 3};
  c.stiffness_cap = 20;  // keeps the explicit step stable when coils bottom out
  return c;
}

BodySpec base_spec(Mesh mesh, double dt) {
  BodySpec b;
  b.mesh = std::move(mesh);
  b.density = 1000;
  b.groups.push_back({"tissue", tissue_card(), kAllFamilies, {}, Vec3::Zero(), 10});
  FixedSelector bottom;  // plane z = 0, all axes
  bottom.tolerance = 1e-9;
  b.fixed.push_back(bottom);
  b.mapping = Mapping::kStrain;
  b.options.integrator = Integrator::kSymplecticEuler;
  b.options.dt = dt;
  b.options.mass_damping = 5;
  b.probes.push_back(ProbeSpec{5e-3, 0});
  return b;
}

// Keeps the hexahedra whose centres pass `inside`, drops unused nodes and renumbers.
template <class Inside>
Mesh carve(const Mesh& box, Inside inside) {
  Mesh out;
  std::vector<int> remap(box.nodes.size(), -1);
  for (const auto& h : box.hexahedra) {
    Vec3 c = Vec3::Zero();
    for (int i : h) c += box.nodes[i];
    if (!inside(c / 8)) continue;
    std::array<int, 8> nh;
    for (int k = 0; k < 8; ++k) {
      int& r = remap[h[k]];
      if (r < 0) {
        r = static_cast<int>(out.nodes.size());
        out.nodes.push_back(box.nodes[h[k]]);
      }
      nh[k] = r;
    }
    out.hexahedra.push_back(nh);
  }
  return out;
}

}  // namespace

std::vector<std::string> builtin_scene_names() { return {"cube", "block", "liver"}; }

std::string builtin_scene(const std::string& name, double dt, BodySpec* spec) {
  if (!(dt > 0) || !std::isfinite(dt)) return "time step must be > 0 s";
  if (name == "cube") {
    *spec = base_spec(make_box_lattice(Vec3(0.04, 0.04, 0.04), {7, 7, 4}), dt);
  } else if (name == "block") {
    *spec = base_spec(make_box_lattice(Vec3(0.08, 0.04, 0.02), {16, 8, 4}), dt);
  } else if (name == "liver") {
    const Vec3 size(0.14, 0.10, 0.05);
    const Mesh box = make_box_lattice(size, {20, 14, 7});
    // A half ellipsoid on z = 0, thicker on the right lobe (+x), narrowing to the left.
    *spec = base_spec(carve(box,
                            [&](const Vec3& c) {
                              const double u = (c.x() - 0.5 * size.x()) / (0.5 * size.x());
                              const double v =
                                  (c.y() - 0.5 * size.y()) / (0.5 * size.y() * (0.75 + 0.25 * u));
                              const double height = size.z() * (0.55 + 0.45 * (0.5 + 0.5 * u));
                              const double w = c.z() / height;
                              return u * u + v * v + w * w <= 1.0;
                            }),
                      dt);
  } else {
    return "unknown builtin scene \"" + name + "\" (cube, block, liver)";
  }
  return {};
}

}  // namespace conica::net
