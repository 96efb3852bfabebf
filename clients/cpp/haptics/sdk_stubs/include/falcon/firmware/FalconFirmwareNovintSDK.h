// Stand-in for libnifalcon's falcon/firmware/FalconFirmwareNovintSDK.h: the firmware policy of
// Novint's own SDK (the nVent firmware, falcon/util/FalconFirmwareBinaryNvent.h).
#pragma once

#include "falcon/core/FalconFirmware.h"

namespace libnifalcon {

class FalconFirmwareNovintSDK : public FalconFirmware {
 public:
  FalconFirmwareNovintSDK();
  ~FalconFirmwareNovintSDK() override;
  bool runIOLoop() override;
};

}  // namespace libnifalcon
