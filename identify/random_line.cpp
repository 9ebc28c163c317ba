#include "identify/random_line.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <utility>

#include "millkit/driveline/model.h"
#include "millkit/driveline/natural_frequencies.h"
#include "millkit/driveline/scene_parameter.h"
#include "millkit/identify/record_generator.h"
#include "millkit/io/input_error.h"

namespace millkit::identify {

namespace {

constexpr double kTwoPi = 6.283185307179586476925;
// Modes are placed inside [kMinModeHz, kMaxModeHz] by this factor, so that an independent
// recomputation (roundoff ~1e-12) never finds one just outside.
constexpr double kModeMargin = 1.01;
// Bounded redraws: stiffness sets per line, lines per case, cases per seed.
constexpr int kStiffnessDraws = 100;
// The links' own two-mass frequencies are drawn this factor inside the mode band: the coupled
// modes spread wider than the links' (over 300 seeds: 25 % instead of 30 % of the lines have a
// mode within 2 Hz of 15 Hz).
constexpr double kLinkBandFactor = 1.5;
constexpr int kLineDraws = 50;
constexpr int kCaseDraws = 20;

constexpr double kMinInertia_kg_m2 = 300.0;
constexpr double kMaxInertia_kg_m2 = 40000.0;
constexpr double kMinDampingRatio = 0.02;
constexpr double kMaxDampingRatio = 0.15;
constexpr double kGapProbability = 0.5;
constexpr double kMinGap_rad = 0.5e-3;
constexpr double kMaxGap_rad = 40e-3;
constexpr double kMinLoad_Nm = 50e3;
constexpr double kMaxLoad_Nm = 300e3;
constexpr double kMinTwistPerGap = 1.0;
constexpr double kMaxTwistPerGap = 10.0;
constexpr double kMinRise_s = 0.002;
constexpr double kMaxRise_s = 0.015;
constexpr double kNominalBite_s = 0.05;
constexpr double kBiteShift_s = 0.01;
constexpr double kInitialSpeed_rad_per_s = 10.0;
constexpr double kDuration_s = 0.3;
constexpr double kMinRate_Hz = 1000.0;
constexpr double kMaxRate_Hz = 10000.0;
constexpr int kMaxChannels = 3;
// Links into a roll (spindles) are where strain gauges usually sit: drawn this many times as often.
constexpr double kSpindleChannelWeight = 3.0;
constexpr double kMinNoise = 0.005;
constexpr double kMaxNoise = 0.02;
constexpr double kGainError = 0.03;
constexpr double kOffsetFraction = 0.02;
constexpr int kAdcBits = 12;
constexpr int kOversample = 8;
constexpr double kPriorDampingFactor = 1.6;
constexpr double kPriorGapFactor = 1.4;
// The variants (random_line.h).
constexpr unsigned long kVariantStream = 0x9E3779B97F4A7C15UL;
constexpr double kMinDriveBandwidth_Hz = 5.0;
constexpr double kMaxDriveBandwidth_Hz = 20.0;
constexpr double kUnreachedDriveLimit_Nm = 1e12;
constexpr double kMinLowpassFraction = 0.1;  // of the record's rate
constexpr double kMaxLowpassFraction = 0.4;
constexpr double kMinFastLowpassFraction = 0.5;  // above half the rate: not an anti-alias filter
constexpr double kMaxFastLowpassFraction = 5.0;
// The fast filter's record is filtered on 64 points a step (linear between them, as a recorder's
// own filter is continuous): at 8 its interpolation error near an impact is 1e-3 of the peak.
constexpr int kFastLowpassOversample = 64;
constexpr double kWidePriorDampingFactor = 3.0;
constexpr double kWidePriorGapFactor = 2.0;
constexpr double kPriorStiffnessFactor = 1.3;
constexpr double kStiffnessBoundFactor = 2.0;

// Uniform draws built on the generator's raw output, identical on every platform.
class Draw {
 public:
  explicit Draw(unsigned long seed) : random_(seed) {}
  // [0, 1) with 53 random bits.
  double Unit() { return static_cast<double>(random_() >> 11) * (1.0 / 9007199254740992.0); }
  double Uniform(double a, double b) { return a + (b - a) * Unit(); }
  double LogUniform(double a, double b) { return a * std::pow(b / a, Unit()); }
  // Integer in [lo, hi].
  int Integer(int lo, int hi) {
    const int k = lo + static_cast<int>(Unit() * (hi - lo + 1));
    return std::min(k, hi);
  }
  bool Chance(double p) { return Unit() < p; }
  unsigned long Bits() { return static_cast<unsigned long>(random_()); }

 private:
  std::mt19937_64 random_;
};

struct Topology {
  std::string kind;  // for the description
  std::vector<std::string> names;
  std::vector<int> parent;  // parent[0] = −1 (the motor); the link runs parent → mass
};

// The shafts from the motor to the last one before the rolls, by how many there are.
std::vector<std::string> HubNames(int count) {
  switch (count) {
    case 1:
      return {"motor"};
    case 2:
      return {"motor", "gearbox"};
    case 3:
      return {"motor", "gearbox", "pinion_stand"};
    case 4:
      return {"motor", "coupling_hub", "gearbox", "pinion_stand"};
    default:
      return {"motor", "coupling_hub", "gearbox", "intermediate_shaft", "pinion_stand"};
  }
}

Topology DrawTopology(int n, Draw& draw) {
  Topology t;
  const int kind = n == 2 ? 0 : draw.Integer(0, 2);
  if (kind == 0) {
    t.kind = "chain";
    t.names = HubNames(n - 1);
    t.names.push_back("roll");
    for (int i = 0; i < n; ++i) t.parent.push_back(i - 1);
  } else if (kind == 1) {
    t.names = HubNames(n - 2);
    t.kind = "stand split at " + t.names.back();
    for (int i = 0; i < n - 2; ++i) t.parent.push_back(i - 1);
    t.names.push_back("upper_roll");
    t.names.push_back("lower_roll");
    t.parent.push_back(n - 3);
    t.parent.push_back(n - 3);
  } else {
    t.kind = "random tree";
    t.parent.push_back(-1);
    for (int i = 1; i < n; ++i) t.parent.push_back(draw.Integer(0, i - 1));
    std::vector<bool> has_child(n, false);
    for (int i = 1; i < n; ++i) has_child[t.parent[i]] = true;
    t.names.push_back("motor");
    for (int i = 1; i < n; ++i) {
      t.names.push_back((has_child[i] ? "hub" : "roll") + std::to_string(i));
    }
  }
  return t;
}

// A roll's link is its spindle ("upper_roll" → "upper_spindle"); other links name both ends.
std::string LinkName(const std::string& from, const std::string& to, bool to_roll) {
  if (!to_roll) return from + "_" + to;
  std::string name = to;
  name.replace(name.find("roll"), 4, "spindle");
  return name;
}

double EffectiveInertia(const driveline::Scene& scene, const driveline::Link& link) {
  const double a = scene.masses[link.from].inertia_kg_m2;
  const double b = scene.masses[link.to].inertia_kg_m2;
  return a * b / (a + b);
}

bool IsRoll(const Topology& t, int mass) {
  if (mass == 0) return false;
  return std::find(t.parent.begin(), t.parent.end(), mass) == t.parent.end();
}

// Masses and links of a line whose modes all lie in the allowed band; false when kStiffnessDraws
// stiffness sets all spread the modes wider than the band.
bool DrawStiffnesses(Draw& draw, driveline::Scene* scene) {
  const double lo_allowed = kMinModeHz * kModeMargin;
  const double hi_allowed = kMaxModeHz / kModeMargin;
  for (int attempt = 0; attempt < kStiffnessDraws; ++attempt) {
    // Each link's own two-mass frequency inside the band: the coupled modes then spread wider,
    // by a factor that depends on the inertia ratios, and one common scale recentres them.
    for (auto& link : scene->links) {
      const double omega =
          kTwoPi * draw.LogUniform(kMinModeHz * kLinkBandFactor, kMaxModeHz / kLinkBandFactor);
      link.stiffness_Nm_per_rad = omega * omega * EffectiveInertia(*scene, link);
    }
    const std::vector<double> modes = ElasticModesHz(*scene);
    const double lo = modes.front(), hi = modes.back();
    if (hi / lo > hi_allowed / lo_allowed) continue;
    // Frequencies scale with sqrt(c): any scale in this range keeps every mode in the band.
    const double scale =
        draw.LogUniform(std::pow(lo_allowed / lo, 2), std::pow(hi_allowed / hi, 2));
    for (auto& link : scene->links) link.stiffness_Nm_per_rad *= scale;
    return true;
  }
  return false;
}

driveline::Scene MakeMassesAndLinks(const Topology& t, Draw& draw) {
  driveline::Scene scene;
  const int n = static_cast<int>(t.names.size());
  for (int i = 0; i < n; ++i) {
    scene.masses.push_back({t.names[i], draw.LogUniform(kMinInertia_kg_m2, kMaxInertia_kg_m2)});
  }
  for (int i = 1; i < n; ++i) {
    driveline::Link link;
    link.name = LinkName(t.names[t.parent[i]], t.names[i], IsRoll(t, i));
    link.from = t.parent[i];
    link.to = i;
    scene.links.push_back(link);
  }
  return scene;
}

// The line's masses, links and stiffnesses; `topology` receives what was drawn.
driveline::Scene DrawLine(Draw& draw, Topology* topology) {
  // The mass count is kept through the redraws: redrawing it would favour short lines, whose
  // modes spread less.
  const int masses = draw.Integer(2, 6);
  for (int attempt = 0; attempt < kLineDraws; ++attempt) {
    *topology = DrawTopology(masses, draw);
    driveline::Scene scene = MakeMassesAndLinks(*topology, draw);
    if (DrawStiffnesses(draw, &scene)) return scene;
  }
  // Last resort, never reached in practice: a two-mass line has one mode, which always fits.
  *topology = DrawTopology(2, draw);
  driveline::Scene scene = MakeMassesAndLinks(*topology, draw);
  const double omega = kTwoPi * draw.LogUniform(kMinModeHz * kModeMargin, kMaxModeHz / kModeMargin);
  scene.links[0].stiffness_Nm_per_rad = omega * omega * EffectiveInertia(scene, scene.links[0]);
  return scene;
}

std::string Format(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof(text), format, value);
  return text;
}

// Fills c->truth_values from c->config; returns the names of those outside their bounds.
std::string TruthValues(RandomLineCase* c) {
  std::string outside;
  c->truth_values.clear();
  for (const auto& free : c->config.free) {
    const double value = free.parameter.Get(c->truth);
    c->truth_values.push_back(value);
    if (value < free.lower || value > free.upper) outside += " " + free.parameter.name;
  }
  return outside;
}

// One draw of the whole case; throws SolverFailure when the record cannot be simulated.
RandomLineCase DrawCase(unsigned long seed, Draw& draw) {
  RandomLineCase c;
  c.seed = seed;
  Topology topology;
  driveline::Scene& truth = c.truth;
  truth = DrawLine(draw, &topology);
  truth.name = "random line " + std::to_string(seed);
  truth.file = "<random line seed " + std::to_string(seed) + ">";
  truth.duration_s = kDuration_s;
  truth.contact = driveline::ContactLaw::kLimited;
  truth.initial_speed_rad_per_s = kInitialSpeed_rad_per_s;

  double largest_gap_rad = 0.0;
  for (auto& link : truth.links) {
    const double zeta = draw.Uniform(kMinDampingRatio, kMaxDampingRatio);
    link.damping_Nms_per_rad =
        2.0 * zeta * std::sqrt(link.stiffness_Nm_per_rad * EffectiveInertia(truth, link));
    if (draw.Chance(kGapProbability)) link.backlash_rad = draw.LogUniform(kMinGap_rad, kMaxGap_rad);
    largest_gap_rad = std::max(largest_gap_rad, link.backlash_rad);
  }

  std::vector<int> rolls;
  for (int i = 0; i < static_cast<int>(truth.masses.size()); ++i) {
    if (IsRoll(topology, i)) rolls.push_back(i);
  }
  for (int roll : rolls) {
    driveline::TorqueSource source;
    source.name = "ramp at " + truth.masses[roll].name;
    source.mass = roll;
    const double rise = draw.Uniform(kMinRise_s, kMaxRise_s);
    source.times_s = {kNominalBite_s, kNominalBite_s + rise};
    source.values_Nm = {0.0, -draw.LogUniform(kMinLoad_Nm, kMaxLoad_Nm)};
    truth.torques.push_back(source);
  }
  // The gaps matter only against the twist the load makes: scale the loads together so that
  // the largest static twist is 1–10 gaps.
  const double twist_per_gap = draw.LogUniform(kMinTwistPerGap, kMaxTwistPerGap);
  if (largest_gap_rad > 0.0) {
    const std::vector<double> static_torque = driveline::StaticLinkTorques(truth);
    double largest_twist_rad = 0.0;
    for (size_t l = 0; l < truth.links.size(); ++l) {
      largest_twist_rad = std::max(
          largest_twist_rad, std::abs(static_torque[l]) / truth.links[l].stiffness_Nm_per_rad);
    }
    if (largest_twist_rad > 0.0) {
      const double scale = twist_per_gap * largest_gap_rad / largest_twist_rad;
      for (auto& source : truth.torques) {
        for (double& v : source.values_Nm) v *= scale;
      }
    }
  }

  // The model's rule is sample_rate >= 4 × its fastest mode with every gap closed, where a
  // `limited` gap counts 2c; doubling stiffnesses raises a mode by sqrt(2) at most, so the
  // fastest is below 170 Hz and every record rate (>= 1 kHz) passes.
  const double rate_Hz = draw.LogUniform(kMinRate_Hz, kMaxRate_Hz);
  truth.sample_rate_Hz = rate_Hz;
  const double bite_s = kNominalBite_s + draw.Uniform(-kBiteShift_s, kBiteShift_s);
  driveline::ParseSceneParameter(truth, "bite_time", truth.file).Set(bite_s, &truth);
  driveline::ValidateScene(truth);

  // Channels: distinct links, drawn without replacement with spindles weighted up.
  const int link_count = static_cast<int>(truth.links.size());
  const int channel_count = draw.Integer(1, std::min(kMaxChannels, link_count));
  std::vector<double> weight(link_count);
  for (int l = 0; l < link_count; ++l) {
    weight[l] = IsRoll(topology, truth.links[l].to) ? kSpindleChannelWeight : 1.0;
  }
  std::vector<int> channel_links;
  for (int k = 0; k < channel_count; ++k) {
    double total = 0.0;
    for (double w : weight) total += w;
    double u = draw.Uniform(0.0, total);
    int pick = -1;
    for (int l = 0; l < link_count; ++l) {
      if (weight[l] == 0.0) continue;
      pick = l;  // the last one left also takes what roundoff leaves over
      if (u < weight[l]) break;
      u -= weight[l];
    }
    channel_links.push_back(pick);
    weight[pick] = 0.0;
  }

  RecordSpec spec;
  spec.defects.sample_rate_Hz = rate_Hz;
  spec.defects.duration_s = kDuration_s;
  spec.defects.noise_fraction = draw.Uniform(kMinNoise, kMaxNoise);
  spec.defects.bits = kAdcBits;
  spec.defects.lowpass_Hz = 0.0;
  spec.defects.oversample = kOversample;
  spec.defects.seed = draw.Bits();
  std::vector<double> offset_fraction;
  for (int l : channel_links) {
    RecordChannel channel;
    channel.column = truth.links[l].name;
    channel.link_index = l;
    channel.gain = draw.Uniform(1.0 - kGainError, 1.0 + kGainError);
    offset_fraction.push_back(draw.Uniform(-kOffsetFraction, kOffsetFraction));
    spec.channels.push_back(channel);
  }

  // The prior's factors are drawn before any simulation, so a redraw after a solver failure
  // consumes the same number of draws whatever failed.
  driveline::Scene& prior = c.prior;
  prior = truth;
  for (auto& link : prior.links) {
    link.damping_Nms_per_rad *= draw.LogUniform(1.0 / kPriorDampingFactor, kPriorDampingFactor);
    if (link.backlash_rad > 0.0) {
      link.backlash_rad *= draw.LogUniform(1.0 / kPriorGapFactor, kPriorGapFactor);
    }
  }
  driveline::ParseSceneParameter(prior, "bite_time", prior.file).Set(kNominalBite_s, &prior);

  // offset_Nm is absolute: a noise-free run gives each channel's peak first.
  RecordSpec clean = spec;
  clean.defects.noise_fraction = 0.0;
  clean.defects.bits = 0;
  for (auto& channel : clean.channels) {
    channel.gain = 1.0;
    channel.offset_Nm = 0.0;
  }
  const Oscillogram clean_record = GenerateRecord(truth, clean);
  for (size_t k = 0; k < spec.channels.size(); ++k) {
    double peak = 0.0;
    for (double v : clean_record.values[k]) peak = std::max(peak, std::abs(v));
    spec.channels[k].offset_Nm = offset_fraction[k] * peak;
  }
  c.record = GenerateRecord(truth, spec);
  c.record_spec = spec;

  c.config = DefaultFitConfig(prior, c.record);
  const std::string outside = TruthValues(&c);

  // The description.
  std::string d = std::to_string(truth.masses.size()) + " masses, " + topology.kind + " (";
  for (size_t i = 0; i < truth.masses.size(); ++i) {
    d +=
        (i ? " " : "") + truth.masses[i].name + " " + Format("%.3g", truth.masses[i].inertia_kg_m2);
  }
  d += " kg·m²); modes";
  for (double f : ElasticModesHz(truth)) d += Format(" %.1f", f);
  d += " Hz; gaps";
  bool any_gap = false;
  for (const auto& link : truth.links) {
    if (link.backlash_rad <= 0.0) continue;
    d += (any_gap ? ", " : " ") + link.name + Format(" %.2f", link.backlash_rad * 1e3);
    any_gap = true;
  }
  d += any_gap ? " mrad" : " none";
  d += "; loads";
  for (const auto& source : truth.torques) {
    d += " " + truth.masses[source.mass].name + Format(" %.3g", -source.values_Nm.back() / 1e3);
  }
  d += " kN·m; channels";
  for (const auto& channel : spec.channels) d += " " + channel.column;
  d += Format(" at %.2f kHz", rate_Hz / 1e3);
  d += Format(", noise %.1f %%", 100.0 * spec.defects.noise_fraction);
  if (!outside.empty()) d += "; truth outside the default bounds:" + outside;
  c.description = d;
  return c;
}

void AddDrive(Draw& draw, RandomLineCase* c) {
  const double bandwidth =
      2.0 * M_PI * draw.LogUniform(kMinDriveBandwidth_Hz, kMaxDriveBandwidth_Hz);
  driveline::Drive drive;
  drive.mass = 0;
  drive.speed_ref_rad_per_s = c->truth.initial_speed_rad_per_s;
  drive.kp = c->truth.masses[0].inertia_kg_m2 * bandwidth;
  drive.ki = drive.kp * bandwidth / 4.0;
  drive.lag_s = 0.1 / bandwidth;
  drive.limit_Nm = kUnreachedDriveLimit_Nm;
  c->truth.drive = c->prior.drive = drive;
  c->record = GenerateRecord(c->truth, c->record_spec);
  c->description += Format("; speed-PI drive on the motor at %.1f Hz", bandwidth / (2.0 * M_PI));
}

void UseContactLaw(driveline::ContactLaw law, RandomLineCase* c) {
  c->truth.contact = c->prior.contact = law;
  c->record = GenerateRecord(c->truth, c->record_spec);
  c->description += std::string("; contact law ") + driveline::ContactLawName(law);
}

// The recorder's first-order filter, its cutoff a log-uniform fraction of the rate, in the record
// and in the fit's channels (the engineer knows the recorder).
void AddLowpass(Draw& draw, bool fast, RandomLineCase* c) {
  const double cutoff_Hz = c->truth.sample_rate_Hz *
                           (fast ? draw.LogUniform(kMinFastLowpassFraction, kMaxFastLowpassFraction)
                                 : draw.LogUniform(kMinLowpassFraction, kMaxLowpassFraction));
  c->record_spec.defects.lowpass_Hz = cutoff_Hz;
  if (fast) c->record_spec.defects.oversample = kFastLowpassOversample;
  c->record = GenerateRecord(c->truth, c->record_spec);
  for (auto& channel : c->config.channels) channel.lowpass_Hz = cutoff_Hz;
  c->description += Format("; recorder low-pass at %.0f Hz", cutoff_Hz);
}

// Every load a step at the bite (rise 0), truth and prior alike.
void StepLoads(RandomLineCase* c) {
  for (auto* scene : {&c->truth, &c->prior}) {
    for (auto& source : scene->torques) source.times_s.back() = source.times_s.front();
  }
  c->record = GenerateRecord(c->truth, c->record_spec);
  c->description += "; loads applied as steps";
}

void WidenPrior(Draw& draw, RandomLineCase* c) {
  for (size_t l = 0; l < c->prior.links.size(); ++l) {
    auto& link = c->prior.links[l];
    const auto& truth = c->truth.links[l];
    link.damping_Nms_per_rad =
        truth.damping_Nms_per_rad *
        draw.LogUniform(1.0 / kWidePriorDampingFactor, kWidePriorDampingFactor);
    if (truth.backlash_rad > 0.0) {
      link.backlash_rad =
          truth.backlash_rad * draw.LogUniform(1.0 / kWidePriorGapFactor, kWidePriorGapFactor);
    }
  }
  c->config = DefaultFitConfig(c->prior, c->record);
  c->description += "; prior dampings within x3, gaps within x2";
}

void FreeStiffness(Draw& draw, RandomLineCase* c) {
  const int l = draw.Integer(0, static_cast<int>(c->prior.links.size()) - 1);
  auto& link = c->prior.links[l];
  link.stiffness_Nm_per_rad *= draw.LogUniform(1.0 / kPriorStiffnessFactor, kPriorStiffnessFactor);
  FreeParameter free;
  free.parameter = driveline::ParseSceneParameter(c->prior, link.name + ".stiffness", "variant");
  free.start = link.stiffness_Nm_per_rad;
  free.lower = free.start / kStiffnessBoundFactor;
  free.upper = free.start * kStiffnessBoundFactor;
  free.scan = true;  // as a [[free]] table gets by default
  c->config.free.push_back(free);
  c->description += "; " + link.name + ".stiffness fitted";
}

}  // namespace

std::vector<double> ElasticModesHz(const driveline::Scene& scene) {
  std::vector<double> modes = driveline::NaturalFrequenciesHz(scene);
  modes.erase(modes.begin());  // the rigid-body mode
  return modes;
}

RandomLineCase MakeRandomLineCase(unsigned long seed) {
  Draw draw(seed);
  std::string last_failure;
  for (int attempt = 0; attempt < kCaseDraws; ++attempt) {
    try {
      return DrawCase(seed, draw);
    } catch (const SolverFailure& failure) {
      last_failure = failure.what();
    }
  }
  throw std::runtime_error("random line seed " + std::to_string(seed) + ": " +
                           std::to_string(kCaseDraws) +
                           " draws in a row failed to simulate; last: " + last_failure);
}

RandomLineCase MakeRandomLineCase(unsigned long seed, RandomLineVariant variant) {
  return MakeRandomLineCase(seed, std::vector<RandomLineVariant>{variant});
}

RandomLineCase MakeRandomLineCase(unsigned long seed,
                                  const std::vector<RandomLineVariant>& variants) {
  RandomLineCase c = MakeRandomLineCase(seed);
  for (size_t k = 0; k < variants.size(); ++k) {
    // The first variant's stream is the one a variant alone takes.
    Draw draw(seed ^ (kVariantStream * (k + 1)));
    switch (variants[k]) {
      case RandomLineVariant::kBase:
        break;
      case RandomLineVariant::kDrive:
        AddDrive(draw, &c);
        break;
      case RandomLineVariant::kWidePrior:
        WidenPrior(draw, &c);
        break;
      case RandomLineVariant::kStiffness:
        FreeStiffness(draw, &c);
        break;
      case RandomLineVariant::kNoPull:
        UseContactLaw(driveline::ContactLaw::kNoPull, &c);
        break;
      case RandomLineVariant::kLinear:
        UseContactLaw(driveline::ContactLaw::kLinear, &c);
        break;
      case RandomLineVariant::kStepLoad:
        StepLoads(&c);
        break;
      case RandomLineVariant::kLowpass:
        AddLowpass(draw, false, &c);
        break;
      case RandomLineVariant::kFastLowpass:
        AddLowpass(draw, true, &c);
        break;
    }
  }
  TruthValues(&c);
  return c;
}

bool ParseRandomLineVariant(const std::string& name, RandomLineVariant* variant) {
  static const std::pair<const char*, RandomLineVariant> kNames[] = {
      {"base", RandomLineVariant::kBase},
      {"drive", RandomLineVariant::kDrive},
      {"wide-prior", RandomLineVariant::kWidePrior},
      {"stiffness", RandomLineVariant::kStiffness},
      {"no-pull", RandomLineVariant::kNoPull},
      {"linear", RandomLineVariant::kLinear},
      {"step-load", RandomLineVariant::kStepLoad},
      {"lowpass", RandomLineVariant::kLowpass},
      {"fast-lowpass", RandomLineVariant::kFastLowpass}};
  for (const auto& [text, value] : kNames) {
    if (name == text) {
      *variant = value;
      return true;
    }
  }
  return false;
}

bool ParseRandomLineVariants(const std::string& names, std::vector<RandomLineVariant>* variants) {
  variants->clear();
  size_t from = 0;
  while (true) {
    const size_t plus = names.find('+', from);
    RandomLineVariant variant;
    if (!ParseRandomLineVariant(names.substr(from, plus - from), &variant)) return false;
    variants->push_back(variant);
    if (plus == std::string::npos) return true;
    from = plus + 1;
  }
}

}  // namespace millkit::identify
