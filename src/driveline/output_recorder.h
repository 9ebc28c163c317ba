// Where both solvers put their output samples (internal to src/driveline, not installed API):
// the sample matrices when options.keep_samples, and always the running peak |link torque| per
// scene link. The peaks are taken from the very values the matrices receive, so Kd is
// bit-identical with and without kept samples. Solvers hand in outputs of the reduced scene
// (Model::reduced_scene); Commit converts them to each object's own units (Model::shaft_factors).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "driveline/simulation.h"

namespace millkit::driveline {

class OutputRecorder {
 public:
  // Sizes the result for `times` (OutputTimes(scene, options)); `result` must outlive this.
  OutputRecorder(const Model& model, const SimulationOptions& options, std::vector<double> times,
                 SimulationResult* result)
      : model_(model), keep_(options.keep_samples), times_(std::move(times)), result_(*result) {
    const int links = static_cast<int>(model.scene().links.size());
    const int masses = static_cast<int>(model.scene().masses.size());
    const ShaftFactors& k = model.shaft_factors();
    geared_ = !k.identity;
    inverse_link_factor_.resize(links);
    for (int l = 0; l < links; ++l) inverse_link_factor_[l] = 1.0 / k.link[l];
    const int samples = static_cast<int>(times_.size());
    result_.peak_abs_torque_Nm.assign(links, 0.0);
    result_.peak_time_s.assign(links, times_.empty() ? 0.0 : times_.front());
    if (keep_) {
      result_.time_s = times_;
      result_.link_torque_Nm.setZero(samples, links);
      result_.link_twist_rad.setZero(samples, links);
      result_.mass_speed_rad_per_s.setZero(samples, masses);
    } else {
      torque_.resize(links);
      twist_.resize(links);
      speed_.resize(masses);
    }
  }

  const std::vector<double>& times() const { return times_; }
  bool keep_samples() const { return keep_; }
  int size() const { return static_cast<int>(times_.size()); }

  // Writable rows for sample k (the matrices' rows, or scratch without kept samples), for outputs
  // of the reduced scene. Call Commit(k) after filling them.
  double* torque(int k) { return keep_ ? result_.link_torque_Nm.row(k).data() : torque_.data(); }
  double* speed(int k) {
    return keep_ ? result_.mass_speed_rad_per_s.row(k).data() : speed_.data();
  }
  double* twist(int k) { return keep_ ? result_.link_twist_rad.row(k).data() : twist_.data(); }

  // Converts sample k to each object's units and folds its link torques into the peaks (first
  // time of the max wins, as maxCoeff does).
  void Commit(int k) { Commit(k, torque(k)); }
  // The same with the (reduced) link torques held elsewhere.
  void Commit(int k, const double* reduced_torque) {
    const size_t links = result_.peak_abs_torque_Nm.size();
    double* row = keep_ ? result_.link_torque_Nm.row(k).data() : nullptr;
    for (size_t l = 0; l < links; ++l) {
      const double m = reduced_torque[l] * inverse_link_factor_[l];  // exact when the factor is 1
      if (keep_) row[l] = m;
      const double a = std::abs(m);
      if (a > result_.peak_abs_torque_Nm[l]) {
        result_.peak_abs_torque_Nm[l] = a;
        result_.peak_time_s[l] = times_[k];
      }
    }
    if (keep_ && geared_) {
      const ShaftFactors& f = model_.shaft_factors();
      double* speed_row = result_.mass_speed_rad_per_s.row(k).data();
      double* twist_row = result_.link_twist_rad.row(k).data();
      for (size_t i = 0; i < f.mass.size(); ++i) speed_row[i] *= f.mass[i];
      for (size_t l = 0; l < links; ++l) twist_row[l] *= f.link[l];
    }
  }

  // Model::Outputs at sample k, then Commit(k).
  void Record(int k, const Phases& phases, const Eigen::VectorXd& z,
              const Eigen::MatrixXd* system_matrix = nullptr) {
    model_.Outputs(phases, z, torque(k), speed(k), twist(k), system_matrix);
    Commit(k);
  }

 private:
  const Model& model_;
  const bool keep_;
  const std::vector<double> times_;
  SimulationResult& result_;
  std::vector<double> torque_, twist_, speed_;  // scratch rows without kept samples
  bool geared_ = false;                          // some gear ratio is not 1
  std::vector<double> inverse_link_factor_;      // 1 / k of each link
};

}  // namespace millkit::driveline
