// Probe-script CSV reader on arbitrary bytes; a script that parses is evaluated at its start,
// middle, end and past it, and mapped through make_absolute, as conica-lab run does.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "io/probe_script.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto r = conica::io::parse_probe_script(text, "fuzz.csv");
  if (!r) return 0;
  conica::io::ProbeScript& s = r.value();
  const double end = s.end_time();
  conica::io::make_absolute(s, conica::Vec3::Zero(), conica::Vec3::Constant(0.04));
  for (int p = 0; p < static_cast<int>(s.probes.size()); ++p)
    for (double t : {-1.0, 0.0, 0.5 * end, end, end + 1.0}) {
      conica::Vec3 x;
      if (std::isfinite(t)) (void)s.position(p, t, &x);
    }
  return 0;
}
