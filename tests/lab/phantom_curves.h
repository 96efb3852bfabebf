// The phantom compression tests of shared/data/phantoms as lab curves, read through
// io/curve_reader.h (the reader the lab app uses).
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "io/curve_reader.h"
#include "lab/compression.h"

namespace conica::lab {

// shared/data/phantoms/<name>, e.g. "EF30_0T/EF30_0T_A1.csv"; a failed read fails the test.
inline Curve ReadPhantom(const std::string& name) {
  const std::string path = std::string(CONICA_SHARED_DIR) + "/data/phantoms/" + name;
  auto r = io::read_curve(path);
  EXPECT_TRUE(r) << r.error();
  Curve c;
  if (r)
    for (const io::CurveSample& s : r.value().samples) c.push_back({s.displacement, s.force});
  return c;
}

}  // namespace conica::lab
