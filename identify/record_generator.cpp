#include "millkit/identify/record_generator.h"

#include <algorithm>
#include <cmath>

#include "identify/instrument_filter.h"
#include "io/toml_section.h"
#include "millkit/driveline/model.h"
#include "millkit/driveline/scene_parameter.h"
#include "millkit/driveline/simulation.h"
#include "millkit/io/input_error.h"

namespace millkit::identify {

double GaussianNoise::Next() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  // 53-bit uniforms in (0, 1]: u1 never 0, so the logarithm is finite.
  constexpr double kScale = 1.0 / 9007199254740992.0;
  const double u1 = (static_cast<double>(random_() >> 11) + 1.0) * kScale;
  const double u2 = static_cast<double>(random_() >> 11) * kScale;
  const double radius = std::sqrt(-2.0 * std::log(u1));
  constexpr double kTwoPi = 6.283185307179586476925;
  spare_ = radius * std::sin(kTwoPi * u2);
  has_spare_ = true;
  return radius * std::cos(kTwoPi * u2);
}

RecordSpec LoadRecordSpec(const std::string& path, driveline::Scene* scene) {
  const toml::table root = LoadTomlFile(path);
  const TomlSection top(root, path, "");
  top.RequireOnlyKeys({"record", "truth", "channel"});
  RecordSpec spec;
  auto& d = spec.defects;
  if (const auto record = top.OptionalTable("record")) {
    record->RequireOnlyKeys({"sample_rate", "duration", "noise", "bits", "full_scale", "lowpass",
                             "oversample", "seed"});
    d.sample_rate_Hz = record->Positive("sample_rate", record->RequiredNumber("sample_rate"));
    d.duration_s = record->NonNegative("duration", record->Number("duration", 0.0));
    d.noise_fraction = record->InRange("noise", record->Number("noise", 0.0), 0.0, 1.0);
    d.bits = static_cast<int>(record->Integer("bits", 0, 0, 24));
    d.full_scale = record->InRange("full_scale", record->Number("full_scale", 1.5), 1.0, 100.0);
    d.lowpass_Hz = record->NonNegative("lowpass", record->Number("lowpass", 0.0));
    d.oversample = static_cast<int>(record->Integer("oversample", 16, 1, 1000));
    d.seed = static_cast<unsigned long>(record->NonNegative("seed", record->Number("seed", 1)));
  } else {
    top.Fail("record", "is required ([record] with sample_rate)");
  }
  if (const auto truth = top.OptionalTable("truth")) {
    for (const auto& [key, node] : truth->table()) {
      const std::string name(key.str());
      const auto parameter = driveline::ParseSceneParameter(*scene, name, truth->KeyContext(name));
      parameter.Set(*truth->OptionalNumber(name), scene);
    }
  }
  driveline::ValidateScene(*scene);
  for (const auto& section : top.TableArray("channel")) {
    section.RequireOnlyKeys({"column", "link", "gain", "offset"});
    RecordChannel c;
    c.column = section.RequiredString("column");
    const std::string link = section.String("link", c.column);
    c.link_index = scene->LinkIndex(link);
    if (c.link_index < 0) section.Fail("link", "no link named '" + link + "' in the scene");
    c.gain = section.Positive("gain", section.Number("gain", 1.0));
    c.offset_Nm = section.Number("offset", 0.0);
    spec.channels.push_back(c);
  }
  if (spec.channels.empty()) top.Fail("channel", "at least one [[channel]] is required");
  return spec;
}

Oscillogram GenerateRecord(const driveline::Scene& truth, const RecordSpec& spec,
                           const std::function<void(double fraction)>& progress) {
  const auto& d = spec.defects;
  driveline::Scene scene = truth;
  if (d.duration_s > 0.0) scene.duration_s = d.duration_s;
  // The fine grid holds every record time: record sample k is fine sample k·oversample.
  scene.sample_rate_Hz = d.sample_rate_Hz * d.oversample;
  const driveline::Model model(std::move(scene));
  driveline::SimulationOptions options;
  options.estimate_error = false;
  options.progress = progress;
  const auto result = driveline::Simulate(model, options);
  if (!result.summary.success) {
    throw SolverFailure("record generator: " + result.summary.message);
  }
  const int fine = static_cast<int>(result.time_s.size());
  const int count = (fine - 1) / d.oversample + 1;
  Oscillogram record;
  record.source = "generated from " + truth.name;
  for (int k = 0; k < count; ++k) {
    record.time_s.push_back(static_cast<double>(k) / d.sample_rate_Hz);
  }
  GaussianNoise noise(d.seed);
  for (const auto& channel : spec.channels) {
    record.channels.push_back(channel.column);
    const auto torque = result.link_torque_Nm.col(channel.link_index);
    // A column of the row-major sample matrix is strided: copy element by element.
    std::vector<double> filtered(fine);
    for (int j = 0; j < fine; ++j) filtered[j] = torque(j);
    FirstOrderLowPass(d.lowpass_Hz, result.time_s, &filtered);
    const double peak = torque.cwiseAbs().maxCoeff();
    double measured_peak = 0.0;
    std::vector<double> values(count);
    for (int k = 0; k < count; ++k) {
      values[k] = channel.gain * filtered[static_cast<size_t>(k) * d.oversample] +
                  channel.offset_Nm + d.noise_fraction * peak * noise.Next();
      measured_peak = std::max(measured_peak, std::abs(values[k]));
    }
    if (d.bits > 0) {
      const double full_scale = d.full_scale * measured_peak;
      const double lsb = 2.0 * full_scale / std::ldexp(1.0, d.bits);
      for (double& v : values) {
        v = std::clamp(std::round(v / lsb) * lsb, -full_scale, full_scale - lsb);
      }
    }
    record.values.push_back(std::move(values));
  }
  return record;
}

}  // namespace millkit::identify
