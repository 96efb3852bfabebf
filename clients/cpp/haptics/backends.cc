// Hardware backends. Each is compiled only when CMake found its SDK (CONICA_HAVE_*); units and
// frames are converted here, at the edge, with the DeviceFrame the caller passes (the native
// frame of the SDK composed with the user's workspace offset and scale).
#include <cmath>

#include "haptics/device.h"

#ifdef CONICA_HAVE_OPENHAPTICS
#include <HD/hd.h>
#endif
#ifdef CONICA_HAVE_DHD
#include <dhdc.h>
#endif
#ifdef CONICA_HAVE_NIFALCON
#include <falcon/core/FalconDevice.h>
#include <falcon/firmware/FalconFirmwareNovintSDK.h>
#include <falcon/kinematic/FalconKinematicStamper.h>
#endif

namespace conica::haptics {

namespace {

#ifdef CONICA_HAVE_OPENHAPTICS
// OpenHaptics HD: mm, Y up. Device calls run inside the HD scheduler thread through
// hdScheduleSynchronous; each read also applies the force written since the last read.
class OpenHapticsDevice : public Device {
 public:
  explicit OpenHapticsDevice(const DeviceFrame& frame) : frame_(frame) {}
  bool open(std::string* error) {
    handle_ = hdInitDevice(HD_DEFAULT_DEVICE);
    HDErrorInfo e = hdGetError();
    if (HD_DEVICE_ERROR(e)) {
      *error = std::string("hdInitDevice: ") + hdGetErrorString(e.errorCode);
      return false;
    }
    hdEnable(HD_FORCE_OUTPUT);
    hdStartScheduler();
    e = hdGetError();
    if (HD_DEVICE_ERROR(e)) {
      *error = std::string("hdStartScheduler: ") + hdGetErrorString(e.errorCode);
      return false;
    }
    return true;
  }
  std::string name() const override { return "openhaptics"; }
  bool read(double, DeviceSample* out) override {
    Exchange x{handle_, {}, {}, {force_.x(), force_.y(), force_.z()}};
    hdScheduleSynchronous(&OpenHapticsDevice::exchange, &x, HD_DEFAULT_SCHEDULER_PRIORITY);
    out->position = to_scene_position(frame_, Vec3(x.pos[0], x.pos[1], x.pos[2]));
    out->velocity = to_scene_velocity(frame_, Vec3(x.vel[0], x.vel[1], x.vel[2]));
    return true;
  }
  void write_force(const Vec3& f) override { force_ = to_native_force(frame_, f); }
  void close() override {
    if (handle_ == HD_INVALID_HANDLE) return;
    force_.setZero();
    DeviceSample s;
    read(0, &s);
    hdStopScheduler();
    hdDisableDevice(handle_);
    handle_ = HD_INVALID_HANDLE;
  }
  ~OpenHapticsDevice() override { close(); }

 private:
  struct Exchange {
    HHD handle;
    HDdouble pos[3], vel[3], force[3];
  };
  static HDCallbackCode HDCALLBACK exchange(void* data) {
    auto* x = static_cast<Exchange*>(data);
    hdBeginFrame(x->handle);
    hdGetDoublev(HD_CURRENT_POSITION, x->pos);
    hdGetDoublev(HD_CURRENT_VELOCITY, x->vel);
    hdSetDoublev(HD_CURRENT_FORCE, x->force);
    hdEndFrame(x->handle);
    return HD_CALLBACK_DONE;
  }
  DeviceFrame frame_;
  HHD handle_ = HD_INVALID_HANDLE;
  Vec3 force_ = Vec3::Zero();
};
#endif

#ifdef CONICA_HAVE_DHD
// Force Dimension DHD: m and N, Z up.
class DhdDevice : public Device {
 public:
  explicit DhdDevice(const DeviceFrame& frame) : frame_(frame) {}
  bool open(std::string* error) {
    if (dhdOpen() < 0) {
      *error = std::string("dhdOpen: ") + dhdErrorGetLastStr();
      return false;
    }
    dhdEnableForce(DHD_ON);
    return true;
  }
  std::string name() const override { return "dhd"; }
  bool read(double, DeviceSample* out) override {
    double p[3], v[3];
    if (dhdGetPosition(&p[0], &p[1], &p[2]) < 0) return false;
    dhdGetLinearVelocity(&v[0], &v[1], &v[2]);
    out->position = to_scene_position(frame_, Vec3(p[0], p[1], p[2]));
    out->velocity = to_scene_velocity(frame_, Vec3(v[0], v[1], v[2]));
    return true;
  }
  void write_force(const Vec3& f) override {
    const Vec3 n = to_native_force(frame_, f);
    dhdSetForce(n.x(), n.y(), n.z());
  }
  void close() override {
    if (!open_) return;
    dhdSetForce(0, 0, 0);
    dhdClose();
    open_ = false;
  }
  ~DhdDevice() override { close(); }

 private:
  DeviceFrame frame_;
  bool open_ = true;
};
#endif

#ifdef CONICA_HAVE_NIFALCON
// libnifalcon: m and N in the Falcon's own frame (Y up), velocity by finite difference.
class FalconDevice : public Device {
 public:
  explicit FalconDevice(const DeviceFrame& frame) : frame_(frame) {}
  bool open(std::string* error) {
    dev_.setFalconFirmware<libnifalcon::FalconFirmwareNovintSDK>();
    dev_.setFalconKinematic<libnifalcon::FalconKinematicStamper>();
    if (!dev_.open(0)) {
      *error = "libnifalcon: cannot open Falcon 0";
      return false;
    }
    if (!dev_.isFirmwareLoaded() && !dev_.getFalconFirmware()->loadFirmware(
                                        true, NOVINT_FALCON_NVENT_FIRMWARE_SIZE,
                                        const_cast<uint8_t*>(NOVINT_FALCON_NVENT_FIRMWARE))) {
      *error = "libnifalcon: cannot load the firmware";
      return false;
    }
    return true;
  }
  std::string name() const override { return "nifalcon"; }
  bool read(double t, DeviceSample* out) override {
    if (!dev_.runIOLoop()) return false;
    const auto p = dev_.getPosition();
    const Vec3 x = to_scene_position(frame_, Vec3(p[0], p[1], p[2]));
    out->velocity =
        (t > t_prev_ && have_prev_) ? Vec3((x - x_prev_) / (t - t_prev_)) : Vec3::Zero();
    out->position = x;
    x_prev_ = x;
    t_prev_ = t;
    have_prev_ = true;
    return true;
  }
  void write_force(const Vec3& f) override {
    const Vec3 n = to_native_force(frame_, f);
    dev_.setForce({n.x(), n.y(), n.z()});
  }
  void close() override {
    dev_.setForce({0, 0, 0});
    dev_.runIOLoop();
    dev_.close();
  }

 private:
  DeviceFrame frame_;
  libnifalcon::FalconDevice dev_;
  Vec3 x_prev_ = Vec3::Zero();
  double t_prev_ = 0;
  bool have_prev_ = false;
};
#endif

}  // namespace

std::vector<BackendInfo> device_backends() {
  std::vector<BackendInfo> b;
  b.push_back({"virtual", true, "a simulated device: scripted hand, tip mass, hand impedance",
               "m, N, scene frame", ""});
#ifdef CONICA_HAVE_OPENHAPTICS
  const bool hd = true;
#else
  const bool hd = false;
#endif
  b.push_back({"openhaptics", hd, "3D Systems Touch, Phantom Omni (OpenHaptics HD)",
               "mm, Y up (converted to m, Z up)",
               "install OpenHaptics (libHD and HD/hd.h) and reconfigure; CMake looks for "
               "library HD (hint: -DOPENHAPTICS_ROOT=DIR)"});
#ifdef CONICA_HAVE_DHD
  const bool dhd = true;
#else
  const bool dhd = false;
#endif
  b.push_back({"dhd", dhd, "Force Dimension omega.x, delta.x, sigma.x (DHD API)", "m, N, Z up",
               "install the Force Dimension SDK (libdhd and dhdc.h) and reconfigure; CMake "
               "looks for library dhd (hint: -DFORCEDIMENSION_ROOT=DIR)"});
#ifdef CONICA_HAVE_NIFALCON
  const bool nf = true;
#else
  const bool nf = false;
#endif
  b.push_back({"nifalcon", nf, "Novint Falcon (libnifalcon)", "m, N, Y up (converted to Z up)",
               "build and install libnifalcon (library nifalcon, headers falcon/...) and "
               "reconfigure; CMake looks for library nifalcon (hint: -DNIFALCON_ROOT=DIR)"});
  return b;
}

std::unique_ptr<Device> open_hardware(const std::string& backend, const DeviceFrame& frame,
                                      std::string* error) {
  (void)frame;
#ifdef CONICA_HAVE_OPENHAPTICS
  if (backend == "openhaptics") {
    auto d = std::make_unique<OpenHapticsDevice>(frame);
    if (!d->open(error)) return nullptr;
    return d;
  }
#endif
#ifdef CONICA_HAVE_DHD
  if (backend == "dhd") {
    auto d = std::make_unique<DhdDevice>(frame);
    if (!d->open(error)) return nullptr;
    return d;
  }
#endif
#ifdef CONICA_HAVE_NIFALCON
  if (backend == "nifalcon") {
    auto d = std::make_unique<FalconDevice>(frame);
    if (!d->open(error)) return nullptr;
    return d;
  }
#endif
  for (const auto& b : device_backends())
    if (b.name == backend) {
      *error = "backend " + backend + " is not built in: " + b.enable;
      return nullptr;
    }
  *error = "unknown device backend \"" + backend + "\" (see --list-devices)";
  return nullptr;
}

}  // namespace conica::haptics
