// A scene: the immutable Model, the live State and the Workspace the loop steps it with, the
// probe limits and the step cost measured when it was prepared. Preparing one (building the
// Model, stepping a copy to measure the cost, sizing the Workspace) allocates and takes from
// milliseconds to seconds, so LoadScene does it on a worker thread (ScenePreparer) and the loop
// only swaps pointers at a tick boundary.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "core/body.h"
#include "core/model.h"
#include "core/step.h"
#include "loop/body_worker.h"
#include "loop/factor_worker.h"
#include "loop/messages.h"

namespace conica::loop {

// Something preparation found worth telling (the caller decides how to log it).
struct Note {
  bool warning = false;  // else informational
  std::string text;
};

struct Scene {
  std::unique_ptr<Model> model;  // stable address; the loop changes options between ticks only
  State state;                   // the live state (at rest when prepared)
  std::unique_ptr<Workspace> workspace;
  ProbeLimits limits;  // the body's box grown by the margin
  double step_us = 0;  // median step cost at rest, us (multi-rate: the body's step and local
                       // models, against the body's period)
  std::vector<Note> notes;
  // Renews the workspace's sparse factor (kFactorCG scenes), declared last: stopped before the
  // workspace goes.
  std::unique_ptr<FactorWorker> factor_worker;
  // Steps the body on a thread of its own (multi-rate serving, options.body_rate_hz > 0); the
  // loop's tick then calls body_worker->tick instead of step.
  std::unique_ptr<BodyWorker> body_worker;
};

struct PrepareOptions {
  double rate_hz = 1000;          // the loop's rate: the step should cost less than a period
  bool refuse_slow_scene = true;  // refuse a scene whose median step cost exceeds the period
  double box_margin = 0.25;       // m: probe positions must lie within the body box grown by this
  int benchmark_steps = 50;       // steps timed on a copy of the rest state
};

// Builds the model from `spec`, times `benchmark_steps` steps of a copy on the steady clock and
// fills *scene (notes even on failure). Returns an error message or "".
std::string prepare_scene(const BodySpec& spec, const PrepareOptions& options, Scene* scene);

// The scene back at rest: a fresh State and Workspace (allocates).
void reset_scene(Scene* scene);

// conica::options_changed for the scene (after its model's options changed between ticks), with
// the factor worker stopped while the workspace is rebuilt and started again after.
void scene_options_changed(Scene* scene);

// What a LoadScene came to: swapped in (ok) or refused, with preparation's notes either way.
struct SceneReport {
  std::string source;  // LoadScene.source
  bool ok = false;
  std::string error;             // when refused
  const Scene* scene = nullptr;  // the scene in use afterwards (valid during the call)
  const std::vector<Note>* notes = nullptr;
};

// LoadScene.source -> spec; returns an error message ("" on success). Called on a worker thread.
using SceneLoader = std::function<std::string(const std::string& source, BodySpec* spec)>;

// One scene preparation at a time on a worker thread. The loop polls ready() at tick boundaries
// (an atomic load) and take()s the result, which joins a thread that has already finished.
class ScenePreparer {
 public:
  ScenePreparer() = default;
  ScenePreparer(const ScenePreparer&) = delete;
  ScenePreparer& operator=(const ScenePreparer&) = delete;
  ~ScenePreparer() { wait(); }

  struct Result {
    std::string source;
    std::string error;             // "" when `scene` is ready to use
    std::unique_ptr<Scene> scene;  // null on failure
    std::vector<Note> notes;
  };

  // Starts loading and preparing `source`; `retired` (a scene no longer in use, may be null) is
  // destroyed on the worker too. Only when !busy().
  void start(std::string source, SceneLoader loader, PrepareOptions options,
             std::unique_ptr<Scene> retired);
  bool busy() const { return worker_.joinable(); }
  bool ready() const { return done_.load(std::memory_order_acquire); }
  // The result of the last start(); blocks until it is ready. Afterwards !busy().
  Result take();
  // Waits for a running preparation and drops its result.
  void wait();

 private:
  std::thread worker_;
  std::atomic<bool> done_{false};
  Result result_;
};

}  // namespace conica::loop
