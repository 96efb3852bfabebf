// How the fixed-rate loop meets the outside: a Transport hands it typed messages and takes its
// typed results; an Observer hears about statistics, rejections and scene changes. Both are
// called on the loop thread only, between or inside ticks, so they must not block for long.
// Implementations: server/net/zmq_transport.h (ZeroMQ + protobuf), loop/memory_transport.h
// (in memory, for tests).
#pragma once

#include <string>

#include "loop/messages.h"
#include "loop/scene.h"

namespace conica::loop {

class Transport {
 public:
  virtual ~Transport() = default;

  // Takes one waiting message into *in (true), or waits for one until the absolute time
  // `deadline_ns` on the loop's clock. False when none came by then; it may also return false
  // earlier (the loop calls again while time remains). A deadline that has passed only looks.
  // A message the transport cannot decode comes as a Rejection with its route.
  virtual bool poll(TimeNs deadline_ns, Incoming* in) = 0;

  // Replies to the sender of a message. False when the reply could not be queued (peer gone,
  // queue full): the loop counts it and never retries. Not called for unroutable messages.
  virtual bool reply(const Route& to, const ForceReply& reply) = 0;
  virtual bool reply(const Route& to, const ControlResult& result) = 0;
  virtual bool reply(const Route& to, const Rejection& error) = 0;

  // A state frame to every subscriber; never blocks (a slow subscriber loses frames).
  virtual void publish(const StateFrame& frame) = 0;
};

class Observer {
 public:
  virtual ~Observer() = default;
  // A fresh statistics snapshot (a few times per second, and when a run ends).
  virtual void on_stats(const LoopStats& stats, const Counters& counters) {
    (void)stats;
    (void)counters;
  }
  // A message was refused (its error reply, if routable, has been sent).
  virtual void on_rejected(Channel channel, const Rejection& why) {
    (void)channel;
    (void)why;
  }
  // A LoadScene finished, swapped in or refused.
  virtual void on_scene(const SceneReport& report) { (void)report; }
};

}  // namespace conica::loop
