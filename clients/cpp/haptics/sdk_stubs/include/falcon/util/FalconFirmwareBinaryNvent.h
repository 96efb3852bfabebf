// Stand-in for libnifalcon's falcon/util/FalconFirmwareBinaryNvent.h, which holds Novint's nVent
// firmware image as a byte array and its size. The names and types are the published ones; the
// bytes here are a short placeholder (not firmware): the fake Falcon accepts exactly this image.
#pragma once

#include <stdint.h>

namespace libnifalcon {

const static uint8_t NOVINT_FALCON_NVENT_FIRMWARE[] = {0xaa, 0x08, 0x00, 0x00, 0x63, 0x6f,
                                                       0x6e, 0x69, 0x63, 0x61, 0x00, 0x01};
const static unsigned int NOVINT_FALCON_NVENT_FIRMWARE_SIZE = sizeof(NOVINT_FALCON_NVENT_FIRMWARE);

}  // namespace libnifalcon
