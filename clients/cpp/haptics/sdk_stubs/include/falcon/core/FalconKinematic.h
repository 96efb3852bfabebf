// Stand-in for libnifalcon's falcon/core/FalconKinematic.h: encoder angles <-> end effector
// position (m) and Cartesian force (N) <-> motor values.
#pragma once

#include <stdint.h>

#include "falcon/core/FalconCore.h"

namespace libnifalcon {

class FalconKinematic : public FalconCore {
 public:
  ~FalconKinematic() override = default;
  virtual bool getForces(double position[3], double cart_force[3], int16_t (&enc_force)[3]) = 0;
  virtual bool getAngles(double position[3], double angles[3]) = 0;
  virtual bool getPosition(int16_t angles[3], double position[3]) = 0;
};

}  // namespace libnifalcon
