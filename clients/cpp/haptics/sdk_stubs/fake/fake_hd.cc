// OpenHaptics HD calls over fake_sdk::hd::Device.
#include <HD/hd.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <vector>

#include "fake_devices.h"

namespace conica::fake_sdk::hd {
namespace {
struct Callback {
  HDSchedulerHandle id;
  HDSchedulerCallback fn;
  void* data;
  HDushort priority;
};
struct World {
  Device dev;
  std::deque<HDErrorInfo> errors;
  std::vector<Callback> async;
  HDSchedulerHandle next_id = 1;
  bool in_frame = false;
  Triple frame_force{};
};
World& world() {
  static World w;
  return w;
}
constexpr HHD kHandle = 0;
void push_error(HDerror code) { world().errors.push_back(HDErrorInfo{code, 0, kHandle}); }
void run_async_once() {
  auto& w = world();
  std::vector<Callback> now = w.async;
  std::stable_sort(now.begin(), now.end(),
                   [](const Callback& a, const Callback& b) { return a.priority > b.priority; });
  for (const Callback& c : now) {
    const bool still = std::any_of(w.async.begin(), w.async.end(),
                                   [&](const Callback& x) { return x.id == c.id; });
    if (!still) continue;  // unscheduled by an earlier callback
    if (c.fn(c.data) == HD_CALLBACK_DONE)
      w.async.erase(std::remove_if(w.async.begin(), w.async.end(),
                                   [&](const Callback& x) { return x.id == c.id; }),
                    w.async.end());
  }
}
}  // namespace

void reset() { world() = World{}; }
Device& device() { return world().dev; }
int scheduled() { return static_cast<int>(world().async.size()); }
int run_servo_ticks(int n) {
  for (int i = 0; i < n && world().dev.scheduler_running; ++i) run_async_once();
  return scheduled();
}

}  // namespace conica::fake_sdk::hd

using conica::fake_sdk::Triple;
using conica::fake_sdk::hd::device;
using conica::fake_sdk::hd::kHandle;
using conica::fake_sdk::hd::push_error;
using conica::fake_sdk::hd::world;

extern "C" {

HHD hdInitDevice(HDstring) {
  auto& d = device();
  if (!d.present) {
    push_error(HD_COMM_ERROR);
    return HD_INVALID_HANDLE;
  }
  if (d.initialised) {
    push_error(HD_DEVICE_ALREADY_INITIATED);
    return HD_INVALID_HANDLE;
  }
  d.initialised = true;
  return kHandle;
}
void hdDisableDevice(HHD h) {
  if (h != kHandle || !device().initialised) return push_error(HD_BAD_HANDLE);
  device().initialised = false;
  device().force_output = false;
  device().motor_force = {};
}
void hdMakeCurrentDevice(HHD h) {
  if (h != kHandle) push_error(HD_BAD_HANDLE);
}
HHD hdGetCurrentDevice(void) { return device().initialised ? kHandle : HD_INVALID_HANDLE; }

void hdBeginFrame(HHD h) {
  auto& w = world();
  if (h != kHandle || !w.dev.initialised) return push_error(HD_BAD_HANDLE);
  if (w.in_frame) {
    ++w.dev.frame_errors;
    return push_error(HD_ILLEGAL_BEGIN);
  }
  w.in_frame = true;
  w.frame_force = {};  // a frame that sets no force renders none
}
void hdEndFrame(HHD h) {
  auto& w = world();
  auto& d = w.dev;
  if (h != kHandle || !w.in_frame) {
    ++d.frame_errors;
    return push_error(HD_ILLEGAL_END);
  }
  w.in_frame = false;
  ++d.frames;
  Triple f = (d.force_output && d.scheduler_running) ? w.frame_force : Triple{};
  const double n = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  if (n > d.nominal_max_force * (1 + 1e-12)) {
    if (d.max_force_clamping) {
      for (double& c : f) c *= d.nominal_max_force / n;
    } else {
      // This fake renders no force for such a frame and reports HD_EXCEEDED_MAX_FORCE.
      ++d.exceeded_max_force;
      push_error(HD_EXCEEDED_MAX_FORCE);
      f = {};
    }
  }
  if (d.inject_error != HD_SUCCESS) {
    push_error(d.inject_error);
    d.inject_error = HD_SUCCESS;
  }
  d.motor_force = f;
  d.motor_log.push_back(f);
}

void hdGetBooleanv(HDenum pname, HDboolean* params) {
  if (pname == HD_FORCE_OUTPUT) {
    *params = device().force_output;
    return;
  }
  push_error(HD_INVALID_ENUM);
}
void hdGetIntegerv(HDenum pname, HDint* params) {
  switch (pname) {
    case HD_CURRENT_BUTTONS:
      *params = device().buttons;
      return;
    case HD_UPDATE_RATE:
      *params = 1000;
      return;
    default:
      push_error(HD_INVALID_ENUM);
  }
}
void hdGetDoublev(HDenum pname, HDdouble* params) {
  const auto& d = device();
  switch (pname) {
    case HD_CURRENT_POSITION:
    case HD_LAST_POSITION:
      std::copy(d.position_mm.begin(), d.position_mm.end(), params);
      return;
    case HD_CURRENT_VELOCITY:
      std::copy(d.velocity_mm_s.begin(), d.velocity_mm_s.end(), params);
      return;
    case HD_CURRENT_FORCE:
      std::copy(world().frame_force.begin(), world().frame_force.end(), params);
      return;
    case HD_LAST_FORCE:
      std::copy(d.motor_force.begin(), d.motor_force.end(), params);
      return;
    case HD_NOMINAL_MAX_FORCE:
    case HD_NOMINAL_MAX_CONTINUOUS_FORCE:
      *params = d.nominal_max_force;
      return;
    default:
      push_error(HD_INVALID_ENUM);
  }
}
void hdGetFloatv(HDenum pname, HDfloat* params) {
  HDdouble v[16] = {};
  hdGetDoublev(pname, v);
  for (int i = 0; i < 3; ++i) params[i] = static_cast<HDfloat>(v[i]);
}
HDstring hdGetString(HDenum pname) {
  return pname == HD_DEVICE_MODEL_TYPE ? "conica fake HD device" : "";
}
void hdSetDoublev(HDenum pname, const HDdouble* params) {
  auto& w = world();
  if (pname != HD_CURRENT_FORCE) return push_error(HD_INVALID_ENUM);
  if (!w.in_frame) {
    ++w.dev.frame_errors;
    return push_error(HD_INVALID_OPERATION);
  }
  w.frame_force = {params[0], params[1], params[2]};
}
void hdSetFloatv(HDenum pname, const HDfloat* params) {
  const HDdouble v[3] = {params[0], params[1], params[2]};
  hdSetDoublev(pname, v);
}

void hdEnable(HDenum cap) {
  if (cap == HD_FORCE_OUTPUT)
    device().force_output = true;
  else if (cap == HD_MAX_FORCE_CLAMPING)
    device().max_force_clamping = true;
  else if (cap != HD_FORCE_RAMPING && cap != HD_SOFTWARE_FORCE_LIMIT)
    push_error(HD_INVALID_ENUM);
}
void hdDisable(HDenum cap) {
  if (cap == HD_FORCE_OUTPUT)
    device().force_output = false;
  else if (cap == HD_MAX_FORCE_CLAMPING)
    device().max_force_clamping = false;
}
HDboolean hdIsEnabled(HDenum cap) {
  if (cap == HD_FORCE_OUTPUT) return device().force_output;
  if (cap == HD_MAX_FORCE_CLAMPING) return device().max_force_clamping;
  return HD_FALSE;
}

HDErrorInfo hdGetError(void) {
  auto& e = world().errors;
  if (e.empty()) return HDErrorInfo{HD_SUCCESS, 0, kHandle};
  const HDErrorInfo x = e.front();
  e.pop_front();
  return x;
}
HDstring hdGetErrorString(HDerror code) {
  switch (code) {
    case HD_SUCCESS:
      return "no error";
    case HD_COMM_ERROR:
      return "communication error (is the device connected?)";
    case HD_DEVICE_ALREADY_INITIATED:
      return "device already initiated";
    case HD_BAD_HANDLE:
      return "bad device handle";
    case HD_EXCEEDED_MAX_FORCE:
      return "exceeded the device's maximum force";
    case HD_ILLEGAL_BEGIN:
      return "frame begun inside a frame";
    case HD_ILLEGAL_END:
      return "frame ended outside a frame";
    case HD_INVALID_OPERATION:
      return "invalid operation";
    case HD_INVALID_ENUM:
      return "invalid parameter name";
    default:
      return "HD error";
  }
}

void hdStartScheduler(void) {
  if (!device().initialised) return push_error(HD_INVALID_OPERATION);
  device().scheduler_running = true;
}
void hdStopScheduler(void) {
  device().scheduler_running = false;
  device().motor_force = {};
}
HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback cb, void* data, HDushort priority) {
  auto& w = world();
  const HDSchedulerHandle id = w.next_id++;
  w.async.push_back({id, cb, data, priority});
  return id;
}
// Returns after one servo tick in which the asynchronous callbacks ran and then this one (until it
// returns HD_CALLBACK_DONE); without a running scheduler it runs the callback directly.
void hdScheduleSynchronous(HDSchedulerCallback cb, void* data, HDushort) {
  if (device().scheduler_running) conica::fake_sdk::hd::run_async_once();
  while (cb(data) == HD_CALLBACK_CONTINUE) {
  }
}
void hdUnschedule(HDSchedulerHandle h) {
  auto& a = world().async;
  a.erase(std::remove_if(a.begin(), a.end(), [&](const auto& c) { return c.id == h; }), a.end());
}
HDboolean hdWaitForCompletion(HDSchedulerHandle h, HDuint) {
  const auto& a = world().async;
  return std::any_of(a.begin(), a.end(), [&](const auto& c) { return c.id == h; });
}
void hdSetSchedulerRate(HDulong) {}

}  // extern "C"
