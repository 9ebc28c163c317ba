// Where both solvers put their output samples (internal to src/driveline, not installed API):
// the sample matrices when options.keep_samples, and always the running peak |link torque| per
// scene link, and each sample to options.sample_sink. The peaks are taken from the very values the
// matrices and the sink receive, so Kd is bit-identical with and without kept samples. Solvers hand
// in outputs of the reduced scene (Model::reduced_scene); Commit converts them to each object's own
// units (Model::shaft_factors).
#pragma once

#include <algorithm>
#include <cmath>
#include <exception>
#include <functional>
#include <vector>

#include "millkit/driveline/simulation.h"

namespace millkit::driveline {

class OutputRecorder {
 public:
  // Sizes the result for the run's output times; `options` and `result` must outlive this.
  OutputRecorder(const Model& model, const SimulationOptions& options, SimulationResult* result)
      : model_(model),
        keep_(options.keep_samples),
        sink_(options.sample_sink),
        progress_(options.progress),
        times_(model.reduced_scene(), options),
        result_(*result) {
    const int links = static_cast<int>(model.scene().links.size());
    const int masses = static_cast<int>(model.scene().masses.size());
    const ShaftFactors& k = model.shaft_factors();
    geared_ = !k.identity;
    inverse_link_factor_.resize(links);
    for (int l = 0; l < links; ++l) inverse_link_factor_[l] = 1.0 / k.link[l];
    const int samples = times_.size();
    result_.peak_abs_torque_Nm.assign(links, 0.0);
    result_.peak_time_s.assign(links, samples == 0 ? 0.0 : times_.front());
    if (keep_) {
      result_.time_s.resize(samples);
      for (int i = 0; i < samples; ++i) result_.time_s[i] = times_[i];
      result_.link_torque_Nm.setZero(samples, links);
      result_.link_twist_rad.setZero(samples, links);
      result_.mass_speed_rad_per_s.setZero(samples, masses);
    } else {
      torque_.resize(links);
      twist_.resize(links);
      speed_.resize(masses);
    }
  }

  const OutputGrid& times() const { return times_; }
  bool keep_samples() const { return keep_; }
  // Whether the speed and twist rows are read (kept or streamed); without, a solver may skip them.
  bool wants_rows() const { return keep_ || sink_; }
  int size() const { return times_.size(); }
  // The exception the sink or progress callback threw, for a solver that catches exceptions
  // around its loop (CVODE) to rethrow.
  std::exception_ptr callback_error() const { return callback_error_; }

  // Writable rows for sample k (the matrices' rows, or scratch without kept samples), for outputs
  // of the reduced scene. Call Commit(k) after filling them.
  double* torque(int k) { return keep_ ? result_.link_torque_Nm.row(k).data() : torque_.data(); }
  double* speed(int k) {
    return keep_ ? result_.mass_speed_rad_per_s.row(k).data() : speed_.data();
  }
  double* twist(int k) { return keep_ ? result_.link_twist_rad.row(k).data() : twist_.data(); }

  // Converts sample k to each object's units, folds its link torques into the peaks (first time
  // of the max wins, as maxCoeff does) and hands it to the sink.
  void Commit(int k) { Commit(k, torque(k)); }
  // The same with the (reduced) link torques held elsewhere.
  void Commit(int k, const double* reduced_torque) {
    const size_t links = result_.peak_abs_torque_Nm.size();
    const bool rows = wants_rows();
    double* row = rows ? torque(k) : nullptr;  // may be reduced_torque itself: read before write
    const double t = times_[k];
    for (size_t l = 0; l < links; ++l) {
      const double m = reduced_torque[l] * inverse_link_factor_[l];  // exact when the factor is 1
      if (rows) row[l] = m;
      const double a = std::abs(m);
      if (a > result_.peak_abs_torque_Nm[l]) {
        result_.peak_abs_torque_Nm[l] = a;
        result_.peak_time_s[l] = t;
      }
    }
    if (rows && geared_) {
      const ShaftFactors& f = model_.shaft_factors();
      double* speed_row = speed(k);
      double* twist_row = twist(k);
      for (size_t i = 0; i < f.mass.size(); ++i) speed_row[i] *= f.mass[i];
      for (size_t l = 0; l < links; ++l) twist_row[l] *= f.link[l];
    }
    if (!sink_ && !progress_) return;
    try {
      if (sink_) sink_({k, t, row, speed(k), twist(k)});
      if (progress_) progress_(static_cast<double>(k + 1) / times_.size());
    } catch (...) {
      callback_error_ = std::current_exception();
      throw;
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
  const std::function<void(const OutputSample&)>& sink_;
  const std::function<void(double)>& progress_;
  const OutputGrid times_;
  SimulationResult& result_;
  std::vector<double> torque_, twist_, speed_;  // scratch rows without kept samples
  bool geared_ = false;                         // some gear ratio is not 1
  std::vector<double> inverse_link_factor_;     // 1 / k of each link
  std::exception_ptr callback_error_;
};

}  // namespace millkit::driveline
