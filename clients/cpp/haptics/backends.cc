// Hardware backends. Each is compiled when CMake found its SDK (CONICA_HAVE_*), or against the
// stub SDK headers of haptics/sdk_stubs for the tests (CONICA_DEVICE_STUB_SDK, linked to the fake
// device library instead of the vendor's). Units and frames are converted here, at the edge, with
// the DeviceFrame the caller passes (the native frame of the SDK composed with the user's
// workspace offset and scale): positions native -> scene, forces scene -> native.
#include <cmath>
#include <mutex>

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
#include <falcon/util/FalconFirmwareBinaryNvent.h>
#endif

namespace conica::haptics {

namespace {

#ifdef CONICA_HAVE_OPENHAPTICS
// OpenHaptics HD: mm, mm/s, Y up. An asynchronous callback in the HD servo thread (1 kHz,
// highest priority) runs one frame per tick: it reads position, velocity and buttons into a
// shared sample and sets the force last written. read() and write_force() only touch the shared
// sample under a mutex, so the servo loop never waits for the HD scheduler.
class OpenHapticsDevice : public Device {
 public:
  explicit OpenHapticsDevice(const DeviceFrame& frame) : frame_(frame) {}
  bool open(std::string* error) {
    const HHD h = hdInitDevice(HD_DEFAULT_DEVICE);
    HDErrorInfo e = hdGetError();
    if (HD_DEVICE_ERROR(e)) {
      *error = std::string("hdInitDevice: ") + hdGetErrorString(e.errorCode);
      return false;
    }
    handle_ = h;
    hdEnable(HD_FORCE_OUTPUT);
    callback_ = hdScheduleAsynchronous(&OpenHapticsDevice::servo, this, HD_MAX_SCHEDULER_PRIORITY);
    hdStartScheduler();
    e = hdGetError();
    if (HD_DEVICE_ERROR(e)) {
      *error = std::string("hdStartScheduler: ") + hdGetErrorString(e.errorCode);
      hdUnschedule(callback_);
      hdDisableDevice(handle_);
      handle_ = HD_INVALID_HANDLE;
      return false;
    }
    return true;
  }
  std::string name() const override { return "openhaptics"; }
  // False until the servo thread has run a frame, and after a device fault.
  bool read(double, DeviceSample* out) override {
    Vec3 pos, vel;
    HDint buttons;
    {
      std::lock_guard<std::mutex> lock(mu_);
      const Shared& s = shared_;
      if (!s.fault.empty() || s.frames == 0) return false;
      pos = Vec3(s.pos[0], s.pos[1], s.pos[2]);
      vel = Vec3(s.vel[0], s.vel[1], s.vel[2]);
      buttons = s.buttons;
    }
    out->position = to_scene_position(frame_, pos);
    out->velocity = to_scene_velocity(frame_, vel);
    out->button = (buttons & HD_DEVICE_BUTTON_1) != 0;
    return true;
  }
  void write_force(const Vec3& f) override {
    const Vec3 n = to_native_force(frame_, f);
    std::lock_guard<std::mutex> lock(mu_);
    shared_.force[0] = n.x();
    shared_.force[1] = n.y();
    shared_.force[2] = n.z();
  }
  std::string fault() const override {
    std::lock_guard<std::mutex> lock(mu_);
    return shared_.fault.empty() ? shared_.warning : shared_.fault;
  }
  // Zero force, one more servo tick to send it, then stop the scheduler and release the device.
  void close() override {
    if (handle_ == HD_INVALID_HANDLE) return;
    write_force(Vec3::Zero());
    hdScheduleSynchronous(&OpenHapticsDevice::after_tick, nullptr, HD_MIN_SCHEDULER_PRIORITY);
    hdStopScheduler();
    hdUnschedule(callback_);
    hdDisableDevice(handle_);
    handle_ = HD_INVALID_HANDLE;
  }
  ~OpenHapticsDevice() override { close(); }

 private:
  struct Shared {
    HDdouble pos[3] = {0, 0, 0}, vel[3] = {0, 0, 0};  // mm, mm/s
    HDint buttons = 0;
    HDdouble force[3] = {0, 0, 0};  // N, native frame
    unsigned long frames = 0;
    std::string fault;    // a device error: the callback has stopped
    std::string warning;  // the last other HD error (e.g. HD_EXCEEDED_MAX_FORCE)
  };
  static HDCallbackCode HDCALLBACK servo(void* data) {
    auto* d = static_cast<OpenHapticsDevice*>(data);
    HDdouble pos[3], vel[3], force[3];
    HDint buttons = 0;
    hdBeginFrame(d->handle_);
    hdGetDoublev(HD_CURRENT_POSITION, pos);
    hdGetDoublev(HD_CURRENT_VELOCITY, vel);
    hdGetIntegerv(HD_CURRENT_BUTTONS, &buttons);
    {
      std::lock_guard<std::mutex> lock(d->mu_);
      Shared& s = d->shared_;
      for (int i = 0; i < 3; ++i) {
        s.pos[i] = pos[i];
        s.vel[i] = vel[i];
        force[i] = s.force[i];
      }
      s.buttons = buttons;
      ++s.frames;
    }
    hdSetDoublev(HD_CURRENT_FORCE, force);
    hdEndFrame(d->handle_);
    for (HDErrorInfo e = hdGetError(); HD_DEVICE_ERROR(e); e = hdGetError()) {
      const std::string what = std::string("HD servo frame: ") + hdGetErrorString(e.errorCode);
      std::lock_guard<std::mutex> lock(d->mu_);
      // Device and communication faults (0x03xx) end the callback; the others are reported.
      if ((e.errorCode & 0xff00) == HD_DEVICE_FAULT) {
        d->shared_.fault = what;
        return HD_CALLBACK_DONE;
      }
      d->shared_.warning = what;
    }
    return HD_CALLBACK_CONTINUE;
  }
  static HDCallbackCode HDCALLBACK after_tick(void*) { return HD_CALLBACK_DONE; }

  DeviceFrame frame_;
  HHD handle_ = HD_INVALID_HANDLE;
  HDSchedulerHandle callback_ = 0;
  mutable std::mutex mu_;
  Shared shared_;
};
#endif

#ifdef CONICA_HAVE_DHD
// Force Dimension DHD: m, m/s, N. Calls return < 0 on error (dhdErrorGetLastStr says why) and
// may return positive non-errors (DHD_TIMEGUARD, DHD_MOTOR_SATURATED).
class DhdDevice : public Device {
 public:
  explicit DhdDevice(const DeviceFrame& frame) : frame_(frame) {}
  bool open(std::string* error) {
    const int id = dhdOpen();
    if (id < 0) {
      *error = std::string("dhdOpen: ") + dhdErrorGetLastStr();
      return false;
    }
    id_ = static_cast<char>(id);
    if (dhdEnableForce(DHD_ON, id_) < 0) {
      *error = std::string("dhdEnableForce: ") + dhdErrorGetLastStr();
      dhdClose(id_);
      return false;
    }
    open_ = true;
    return true;
  }
  std::string name() const override { return "dhd"; }
  bool read(double, DeviceSample* out) override {
    double p[3], v[3];
    if (dhdGetPosition(&p[0], &p[1], &p[2], id_) < 0) return failed("dhdGetPosition");
    if (dhdGetLinearVelocity(&v[0], &v[1], &v[2], id_) < 0) return failed("dhdGetLinearVelocity");
    out->position = to_scene_position(frame_, Vec3(p[0], p[1], p[2]));
    out->velocity = to_scene_velocity(frame_, Vec3(v[0], v[1], v[2]));
    out->button = dhdGetButton(0, id_) == DHD_ON;
    return true;
  }
  void write_force(const Vec3& f) override {
    const Vec3 n = to_native_force(frame_, f);
    const int rc = dhdSetForce(n.x(), n.y(), n.z(), id_);
    if (rc < 0) {
      failed("dhdSetForce");
    } else if (rc == DHD_MOTOR_SATURATED) {
      fault_ = "dhdSetForce: motors saturated (the profile's max force exceeds the device's)";
    }
  }
  std::string fault() const override { return fault_; }
  void close() override {
    if (!open_) return;
    dhdSetForce(0, 0, 0, id_);
    dhdEnableForce(DHD_OFF, id_);
    dhdClose(id_);
    open_ = false;
  }
  ~DhdDevice() override { close(); }

 private:
  bool failed(const char* call) {
    fault_ = std::string(call) + ": " + dhdErrorGetLastStr();
    return false;
  }
  DeviceFrame frame_;
  char id_ = -1;
  bool open_ = false;
  std::string fault_;
};
#endif

#ifdef CONICA_HAVE_NIFALCON
// libnifalcon: m and N in the Falcon's own frame (Y up, Z toward the user), velocity by finite
// difference. Each read runs one I/O loop, which also sends the force set by the last write.
// The Falcon reports positions only once homed (homing mode is requested on every packet; the
// user pulls the grip out and pushes it back in); until then read() fails and says so.
class NiFalconDevice : public Device {
 public:
  explicit NiFalconDevice(const DeviceFrame& frame) : frame_(frame) {}
  bool open(std::string* error) {
    dev_.setFalconFirmware<libnifalcon::FalconFirmwareNovintSDK>();
    dev_.setFalconKinematic<libnifalcon::FalconKinematicStamper>();
    unsigned int count = 0;
    if (!dev_.getDeviceCount(count) || count == 0) {
      *error = "libnifalcon: no Novint Falcon found";
      return false;
    }
    if (!dev_.open(0)) {
      *error =
          "libnifalcon: cannot open Falcon 0 (error " + std::to_string(dev_.getErrorCode()) + ")";
      return false;
    }
    bool loaded = dev_.isFirmwareLoaded();
    for (int attempt = 0; !loaded && attempt < 10; ++attempt)
      loaded = dev_.getFalconFirmware()->loadFirmware(
          true, libnifalcon::NOVINT_FALCON_NVENT_FIRMWARE_SIZE,
          const_cast<uint8_t*>(libnifalcon::NOVINT_FALCON_NVENT_FIRMWARE));
    if (!loaded) {
      *error = "libnifalcon: cannot load the nVent firmware (error " +
               std::to_string(dev_.getFalconFirmware()->getErrorCode()) + ")";
      dev_.close();
      return false;
    }
    dev_.getFalconFirmware()->setHomingMode(true);
    open_ = true;
    return true;
  }
  std::string name() const override { return "nifalcon"; }
  bool read(double t, DeviceSample* out) override {
    if (!dev_.runIOLoop()) {
      fault_ = "libnifalcon: I/O loop failed (error " +
               std::to_string(dev_.getFalconFirmware()->getErrorCode()) + ")";
      return false;
    }
    if (!dev_.getFalconFirmware()->isHomed()) {
      fault_ = "libnifalcon: not homed yet; pull the grip all the way out, then push it in";
      have_prev_ = false;
      return false;
    }
    fault_.clear();
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
  std::string fault() const override { return fault_; }
  void close() override {
    if (!open_) return;
    dev_.setForce({0, 0, 0});
    dev_.runIOLoop();
    dev_.close();
    open_ = false;
  }
  ~NiFalconDevice() override { close(); }

 private:
  DeviceFrame frame_;
  libnifalcon::FalconDevice dev_;
  bool open_ = false;
  std::string fault_;
  Vec3 x_prev_ = Vec3::Zero();
  double t_prev_ = 0;
  bool have_prev_ = false;
};
#endif

#ifdef CONICA_DEVICE_STUB_SDK
constexpr const char* kStubNote = " [stub SDK and fake device: tests only]";
#else
constexpr const char* kStubNote = "";
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
  b.push_back({"openhaptics", hd,
               std::string("3D Systems Touch, Phantom Omni (OpenHaptics HD)") + kStubNote,
               "mm, Y up (converted to m, Z up)",
               "install OpenHaptics (libHD and HD/hd.h) and reconfigure; CMake looks for "
               "library HD (hint: -DOPENHAPTICS_ROOT=DIR)"});
#ifdef CONICA_HAVE_DHD
  const bool dhd = true;
#else
  const bool dhd = false;
#endif
  b.push_back({"dhd", dhd,
               std::string("Force Dimension omega.x, delta.x, sigma.x (DHD API)") + kStubNote,
               "m, N, Z up",
               "install the Force Dimension SDK (libdhd and dhdc.h) and reconfigure; CMake "
               "looks for library dhd (hint: -DFORCEDIMENSION_ROOT=DIR)"});
#ifdef CONICA_HAVE_NIFALCON
  const bool nf = true;
#else
  const bool nf = false;
#endif
  b.push_back({"nifalcon", nf, std::string("Novint Falcon (libnifalcon)") + kStubNote,
               "m, N, Y up (converted to Z up)",
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
    auto d = std::make_unique<NiFalconDevice>(frame);
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
