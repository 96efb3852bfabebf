// Stand-in for libnifalcon's falcon/kinematic/FalconKinematicStamper.h: the Falcon's direct and
// inverse kinematics after R. E. Stamper (position in m, force in N).
#pragma once

#include <stdint.h>

#include "falcon/core/FalconKinematic.h"

namespace libnifalcon {

class FalconKinematicStamper : public FalconKinematic {
 public:
  explicit FalconKinematicStamper(bool init_now = true);
  ~FalconKinematicStamper() override {}
  void initialize();
  bool getForces(double position[3], double cart_force[3], int16_t (&enc_force)[3]) override;
  bool getAngles(double position[3], double angles[3]) override;
  bool getPosition(int16_t angles[3], double position[3]) override;
};

}  // namespace libnifalcon
