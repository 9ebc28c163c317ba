// Test and bench support (issue 11): the hard scenes of the stiff-phase issue, each with the
// parameter that makes it stiff.
#pragma once

#include "scene_builder.h"

namespace millkit::driveline::testing {

// Near-step load: two masses (1000 and 500 kg·m²), c = 1e6 N·m/rad, d = 100, gap 20 mrad, 10 kHz
// for 0.2 s; loads ±1000 N·m from 0.01 s ramping over `rise` (s).
inline Scene NearStepScene(double rise) {
  Scene scene = TwoMassScene(1000.0, 500.0, 1e6, 100.0, 0.02, 0.2, 10000.0);
  scene.torques = {Step(0, 0.0, 1000.0, 0.01, rise), Step(1, 0.0, -1000.0, 0.01, rise)};
  return scene;
}

// Fast drive loop: one mass 0.001 kg·m² on a P-only drive (kp = 1, limit 10 N·m, speed_ref
// −100 rad/s) with the given torque lag (s), sampled at 10 Hz for 10 s.
inline Scene FastDriveScene(double lag) {
  Scene scene;
  scene.duration_s = 10.0;
  scene.sample_rate_Hz = 10.0;
  scene.masses = {{"m", 0.001}};
  scene.drive = Drive{0, -100.0, 1.0, 0.0, lag, 10.0};
  return scene;
}

// Heavy damping: two masses of 1 kg·m², c = 1e4, gap 10 mrad, load −100 N·m from 0.05 s over
// 1 ms, 1 kHz for 0.2 s, with the given damping (N·m·s/rad).
inline Scene HeavyDampingScene(double damping) {
  Scene scene = TwoMassScene(1.0, 1.0, 1e4, damping, 0.01, 0.2, 1000.0);
  scene.torques = {Step(1, 0.0, -100.0, 0.05, 1e-3)};
  return scene;
}

}  // namespace millkit::driveline::testing
