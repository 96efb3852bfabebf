// What the scene benchmarks (bench_implicit, bench_multirate) share: a scene file built into a
// model with a probe, the thread's CPU clock and percentiles.
#pragma once

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <optional>
#include <string>
#include <vector>

#include "core/body.h"
#include "io/scene.h"

namespace conica::bench {

// The scene at `path` built into *m; false (the reason on stderr) when it cannot be read or built
// or has no probe.
// `contact`: every probe takes this contact model (its stiffness the default: from the tissue, or
// for the node law from the masses and the step), whatever the scene says; none: the scene's.
inline bool LoadProbedScene(const std::string& path, Model* m,
                            std::optional<ContactModel> contact = std::nullopt) {
  BodySpec spec;
  if (std::string e = io::load_scene(path, &spec); !e.empty()) {
    std::fprintf(stderr, "%s\n", e.c_str());
    return false;
  }
  if (contact)
    for (ProbeSpec& p : spec.probes) {
      p.contact = *contact;
      p.stiffness = 0;
    }
  if (std::string e = build_model(spec, m); !e.empty() || m->probes.empty()) {
    std::fprintf(stderr, "%s\n", e.empty() ? "the scene has no probe" : e.c_str());
    return false;
  }
  return true;
}

inline double ThreadCpuUs() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e6 * t.tv_sec + 1e-3 * t.tv_nsec;
}

// The q-quantile of v (nearest rank; 0 for none).
inline double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * v.size()))];
}

}  // namespace conica::bench
